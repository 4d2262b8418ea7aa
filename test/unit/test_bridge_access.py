"""bridge.access: a non-loopback bridge needs authentication; the token file must be private."""
import os

import pytest

from inspection_robot.bridge.access import AccessError, is_loopback, listen_check, read_token_file


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
