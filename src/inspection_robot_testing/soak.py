"""soak: the command line of the chaos soak of the simulated robot (ros/soak.py drives it; scripts/soak
starts sim.launch and this). Test harness, not installed: run from the devel space, not with rosrun.

Usage: python3 -m inspection_robot_testing.soak --minutes M [--seed S] [--warmup S] [--isapi-port P]
       [--faults WORD,...] [--respawn-limit S]   (inside scripts/rosenv, sim.launch running; scripts/soak starts both)
"""
import argparse
import sys

from inspection_robot_testing.ros import soak


def main():
    parser = argparse.ArgumentParser(description=soak.__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--warmup", type=float, default=None,
                        help="s of memory warm-up after the look-round (default: 20%% of the run, >= 30 s, <= half)")
    parser.add_argument("--isapi-port", type=int, default=None,
                        help="serve the fake ISAPI camera here (sim.launch camera_isapi_url:=http://127.0.0.1:PORT)"
                             " and inject its faults")
    parser.add_argument("--respawn-limit", type=float, default=5.0,
                        help="s a killed node may take to come back (process, registration, topics); make test's "
                             "soak allows more: on a loaded CI machine a start takes what the CPU gives it")
    parser.add_argument("--faults", default="",
                        help="only the faults whose names contain one of these comma-separated words (e.g. kill)")
    # roslaunch appends __name:=... and __log:=... when it runs this as a node
    soak.run(parser.parse_args([a for a in sys.argv[1:] if ":=" not in a]))


if __name__ == "__main__":
    main()
