"""bridge.access: a non-loopback bridge needs authentication; the token file must be private."""
import os

import pytest

from inspection_robot.bridge.access import (AccessError, FailureLimiter, Peer, is_loopback, listen_check,
                                            origin_allowed, read_token_file)


@pytest.mark.parametrize("address,expected", [("127.0.0.1", True), ("127.0.1.1", True), ("::1", True),
                                              ("localhost", True), ("", False), ("0.0.0.0", False),
                                              ("192.168.1.10", False), ("::", False), ("robot.local", False)])
def test_is_loopback(address, expected):
    assert is_loopback(address) is expected


def test_open_bind_refused_with_the_fix():
    with pytest.raises(AccessError) as err:
        listen_check("0.0.0.0", False, False, False)
    assert str(err.value).startswith("refusing to listen on 0.0.0.0 without authentication: set ~auth_token_file")
    with pytest.raises(AccessError, match="refusing to listen on 0.0.0.0"):
        listen_check("", False, False, False)


def test_accepted_binds():
    assert listen_check("127.0.0.1", False, False, False) is None
    assert listen_check("0.0.0.0", True, False, False) is None
    assert listen_check("0.0.0.0", False, True, False) is None


def test_insecure_returns_the_warning():
    assert listen_check("10.0.0.5", False, False, True).startswith(
        "INSECURE: the backend link listens on 10.0.0.5 without authentication")


def write(tmp_path, text, mode):
    path = tmp_path / "token"
    path.write_text(text)
    os.chmod(str(path), mode)
    return str(path)


def test_token_file_private(tmp_path):
    assert read_token_file(write(tmp_path, "s3cret\n", 0o600)) == "s3cret"
    assert read_token_file(write(tmp_path, "s3cret", 0o400)) == "s3cret"


@pytest.mark.parametrize("mode", [0o640, 0o604, 0o644, 0o660, 0o602])
def test_token_file_readable_by_others_refused(tmp_path, mode):
    with pytest.raises(AccessError, match="accessible by group/others \\(mode %03o\\): chmod 600" % mode):
        read_token_file(write(tmp_path, "s3cret", mode))


def test_token_file_missing_or_empty(tmp_path):
    with pytest.raises(AccessError, match="No such file"):
        read_token_file(str(tmp_path / "absent"))
    with pytest.raises(AccessError, match="is empty"):
        read_token_file(write(tmp_path, " \n", 0o600))


@pytest.mark.parametrize("origin,host,scheme,allowed", [
    ("http://127.0.0.1:9090", "127.0.0.1:9090", "http", True),        # the console on its own bridge
    ("https://192.168.1.20:9090", "192.168.1.20:9090", "https", True),
    ("http://localhost:9090", "localhost:9090", "http", True),
    ("http://[::1]:9090", "[::1]:9090", "http", True),
    ("HTTP://LOCALHOST:9090", "localhost:9090", "http", True),
    ("http://127.0.0.1:8000", "127.0.0.1:9090", "http", False),       # another port is another site
    ("https://127.0.0.1:9090", "127.0.0.1:9090", "http", False),      # another scheme too
    ("http://evil.example:9090", "evil.example:9090", "http", False),  # DNS rebinding to the robot
    ("http://evil.example", "127.0.0.1:9090", "http", False),
    ("null", "127.0.0.1:9090", "http", False),                         # sandboxed frame, file://
    ("file://", "127.0.0.1:9090", "http", False),
    ("", "127.0.0.1:9090", "http", False),
    ("http://127.0.0.1:99999", "127.0.0.1:9090", "http", False),     # unparsable port
])
def test_origin_allowed_same_origin_console_only(origin, host, scheme, allowed):
    assert origin_allowed(origin, host, scheme) is allowed


def test_origin_allow_list_and_local_names():
    allowed = ("https://backend.example:8443", "http://ops.station")
    assert origin_allowed("https://backend.example:8443", "10.0.0.5:9090", "https", allowed)
    assert origin_allowed("http://ops.station:80", "10.0.0.5:9090", "https", allowed)
    assert not origin_allowed("https://backend.example", "10.0.0.5:9090", "https", allowed)
    assert not origin_allowed("http://robot7:9090", "robot7:9090", "http")
    assert origin_allowed("http://robot7:9090", "robot7:9090", "http", local_names=("robot7",))


def test_failure_limiter_window():
    now = [0.0]
    limiter = FailureLimiter(lambda: now[0], max_failures=2, period=10.0)
    limiter.failed("a")
    assert limiter.blocked_for("a") == 0.0
    now[0] = 5.0
    limiter.failed("a")
    assert limiter.blocked_for("a") == 10.0 and limiter.blocked_for("b") == 0.0
    now[0] = 11.0  # the first failure left the window
    assert limiter.blocked_for("a") == 0.0
    now[0] = 30.0
    assert limiter.blocked_for("a") == 0.0 and not limiter._failures


def test_peer_private():
    assert Peer("127.0.0.1", False).private and Peer("::1", False).private and Peer("10.0.0.9", True).private
    assert not Peer("10.0.0.9", False).private
