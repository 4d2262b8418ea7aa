"""bridge/service_calls: how far a failed call's request got (from rospy's own exception texts), when
the bridge calls again, and the read-only list against the commands the nodes have."""
import pytest

from inspection_robot import interface
from inspection_robot.bridge import service_calls as sc

# what Noetic's rospy raises (rospy/impl/tcpros_service.py ServiceProxy.call, tcpros_base.py)
ROSPY_FAILURES = [
    ("ServiceException", "service [/file_control] unavailable", sc.NOT_SENT),
    ("ServiceException", "unable to contact master", sc.NOT_SENT),
    ("ServiceException", "unable to connect to service: [Errno 111] Connection refused", sc.NOT_SENT),
    ("ServiceException", "unable to connect to service: remote error reported: request from [/b]: md5sums do not "
                         "match: [a] vs. [b]", sc.REFUSED),
    ("TransportTerminated", "32Broken pipe", sc.NOT_SENT),                      # send_message's write, unwrapped
    ("TransportInitError", "TCPROS transport was not successfully initialized", sc.NOT_SENT),
    ("ServiceException", "transport error completing service call: unable to receive data from sender, check "
                         "sender's logs for details", sc.MAY_HAVE_RUN),
    ("ServiceException", "service [/file_control] responded with an error: b'error processing request: x'",
     sc.ANSWERED),
    ("ServiceException", "service [/file_control] returned no response", sc.ANSWERED),
    ("ROSInterruptException", "node shutdown interrupted service call", sc.ANSWERED),
]


@pytest.mark.parametrize("name, text, stage", ROSPY_FAILURES)
def test_each_rospy_failure_says_how_far_the_request_got(name, text, stage):
    assert sc.failure_stage(name, text) == stage


def test_a_socket_error_of_the_write_is_not_sent():
    assert sc.failure_stage("ConnectionResetError", "[Errno 104] Connection reset by peer", is_os_error=True) == \
        sc.NOT_SENT


def test_called_again_only_when_not_sent_or_read_only():
    assert sc.may_call_again(sc.NOT_SENT, read_only=False)
    assert sc.may_call_again(sc.MAY_HAVE_RUN, read_only=True)
    assert not sc.may_call_again(sc.MAY_HAVE_RUN, read_only=False)   # e.g. calibration mark_box: it may have run
    for stage in (sc.REFUSED, sc.ANSWERED):
        assert not sc.may_call_again(stage, read_only=True)


def test_read_only_by_service_base_name_command_and_type():
    control = sc.CONTROL_SERVICE_TYPE
    assert sc.is_read_only("/file_control", control, "stat")
    assert sc.is_read_only("/robot_7/file_control", control, "read")
    assert sc.is_read_only("/calibration_control", control, "get")
    assert sc.is_read_only("/task_control", control, "query_status")
    assert not sc.is_read_only("/calibration_control", control, "mark_box")
    assert not sc.is_read_only("/task_control", control, "submit")
    assert not sc.is_read_only("/task_control", control, "export_results")   # writes a snapshot file
    assert not sc.is_read_only("/file_control", "std_srvs/Trigger", "stat")
    assert not sc.is_read_only("/sim/file_control_x", control, "stat")
    assert not sc.is_read_only("/file_control", control, None)


def test_the_failure_text_names_the_service_and_why():
    text = sc.failure_text("/file_control", sc.NOT_SENT, "service [/file_control] unavailable")
    assert text.startswith("service /file_control is not available: its node is restarting or down (")
    text = sc.failure_text("/calibration_control", sc.MAY_HAVE_RUN, "transport error completing service call: x")
    assert text.startswith("service /calibration_control failed: its node closed the connection before answering")
    assert sc.failure_text("/x", sc.ANSWERED, "bad") == "service /x failed: bad"


def test_every_read_only_command_is_a_command_of_its_node():
    known = {
        "terrace_control": interface.TERRACE_COMMANDS, "arm_control": interface.ARM_COMMANDS,
        "camera_control": interface.CAMERA_COMMANDS, "infrared_control": interface.INFRARED_COMMANDS,
    }
    for service, commands in known.items():
        assert set(interface.READ_ONLY_COMMANDS[service]) <= set(commands), service
    assert set(interface.READ_ONLY_COMMANDS) == set(known) | {"file_control", "calibration_control", "task_control"}
    for commands in interface.READ_ONLY_COMMANDS.values():
        assert not any(name.startswith(("set_", "save_", "capture", "record", "clear", "apply", "upload", "submit"))
                       for name in commands)
