"""Backend demo over the websocket: heartbeat, take remote control, drive 0.6 m, turn the head.

Start the robot first (`make run`), then: .venv/bin/python scripts/backend_demo.py [port]
(the test venv has roslibpy, an unmodified rosbridge client).
"""
import sys
import threading
import time

import roslibpy


def heartbeat(ros, beat, period=1.0):
    """server_status every second: the robot goes offline after 3 s without one."""
    while ros.is_connected:
        beat.publish(roslibpy.Message({"sender": "server", "data": "alive"}))
        time.sleep(period)


def main(port=9090):
    ros = roslibpy.Ros("127.0.0.1", port)
    ros.run()
    status = []
    roslibpy.Topic(ros, "/robot_status", "inspection_robot/RobotStatus").subscribe(status.append)
    beat = roslibpy.Topic(ros, "/server_status", "inspection_robot/GeneralTopic")
    threading.Thread(target=heartbeat, args=(ros, beat), daemon=True).start()
    while not status or status[-1]["offline_warn"]:  # online before taking control
        time.sleep(0.1)

    mode = roslibpy.Topic(ros, "/mode_cmd", "inspection_robot/GeneralCmd")
    move = roslibpy.Topic(ros, "/move_cmd", "inspection_robot/MoveCmd")
    mode.publish(roslibpy.Message({"sender": "server", "cmd": "acquire", "data": "server"}))
    for _ in range(40):  # 0.3 m/s (unit 0.001 m/s) for 2 s at 20 Hz; when the stream stops, the robot stops
        move.publish(roslibpy.Message({"sender": "server", "velocity_x": 300, "velocity_yaw": 0,
                                       "wheel_control": 0}))
        time.sleep(0.05)

    head = roslibpy.Service(ros, "/terrace_control", "inspection_robot/ControlService")
    print(head.call(roslibpy.ServiceRequest({"sender": "server", "cmd": "set_angle", "data": "4500,1000"})))
    print("mode", status[-1]["mode"], "position", status[-1]["position"])
    mode.publish(roslibpy.Message({"sender": "server", "cmd": "release", "data": ""}))
    ros.terminate()


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 9090)
