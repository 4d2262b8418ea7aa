"""replay_player: rosbag play for replay.launch, so that the end of the bag is a normal end.

roslaunch reports a ``required`` node that exits, even with status 0, as a red ``REQUIRED process
[...] has died!``, and ROS 1 has no other way for a node to end a launch. This wrapper therefore is
not required: it runs rosbag's ``play`` executable as its child with its own arguments (remappings
and the node name included, so ``replay_player/pause_playback`` is rosbag's) and, with ``--at-end
exit``, when play has ended asks the roslaunch that started it to shut down as Ctrl-C does (SIGINT):
every node stops cleanly and roslaunch exits 0. Only a parent whose command line is roslaunch is
signalled (never rostest or a shell). ``--at-end hold`` leaves the replay up showing the bag's last
state (the clock stops) until Ctrl-C. A play that fails (missing or truncated bag) ends the launch
too, with play's exit status reported by roslaunch.

Usage (replay.launch): replay_player --at-end exit|hold [rosbag play arguments...]
ROS API: that of rosbag play (publishes the bag's topics and /clock; service ~pause_playback).
"""
import os
import signal
import subprocess
import sys

import roslib.packages

from inspection_robot.ros.node import renice_from_environment

AT_END = ("exit", "hold")


def split_args(argv):
    """(at_end, play arguments) of our command line; ValueError for a missing or unknown --at-end."""
    if len(argv) < 2 or argv[0] != "--at-end" or argv[1] not in AT_END:
        raise ValueError("usage: replay_player --at-end exit|hold [rosbag play arguments...], got %r"
                         % (" ".join(argv[:2]),))
    return argv[1], list(argv[2:])


def launched_by_roslaunch(pid):
    """True when process ``pid`` runs roslaunch (not rostest, not a shell)."""
    try:
        with open("/proc/%d/cmdline" % pid, "rb") as f:
            words = f.read().split(b"\0")
    except OSError:
        return False
    return any(os.path.basename(w) == b"roslaunch" for w in words[:3])


def main():
    try:
        at_end, args = split_args(sys.argv[1:])
    except ValueError as exc:
        print("replay_player: %s" % exc, file=sys.stderr)
        sys.exit(2)
    found = roslib.packages.find_node("rosbag", "play")
    if not found:
        print("replay_player: rosbag's play executable not found (install ros-noetic-rosbag)", file=sys.stderr)
        sys.exit(2)
    # play runs in this process's session: INSPECTION_ROBOT_NICE reaches it as it reaches the nodes it
    # replays to (make test's suites), so that on a busy CPU the bag does not run ahead of them
    not_reniced = renice_from_environment()
    if not_reniced:
        print("replay_player: %s" % not_reniced, file=sys.stderr)
    child = subprocess.Popen([found[0]] + args)
    while True:
        try:
            code = child.wait()
            break
        except KeyboardInterrupt:   # roslaunch stops us (and play, same process group): wait for play
            continue
    parent = os.getppid()
    if at_end == "exit" and launched_by_roslaunch(parent):
        why = "end of the bag" if code == 0 else "rosbag play failed (status %d)" % code
        print("replay_player: %s; ending the replay" % why, flush=True)
        os.kill(parent, signal.SIGINT)
    elif code == 0:
        print("replay_player: end of the bag; the last state stays shown until Ctrl-C", flush=True)
    sys.exit(code if code >= 0 else 128 - code)
