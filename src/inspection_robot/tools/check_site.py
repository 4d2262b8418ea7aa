"""check_site: may robot.launch start with this site file? (inspection_robot.site.check)

    check_site [SITE_FILE] [--data-root DIR] [--ns NS] [--insecure true|false]

robot.launch runs it while roslaunch parses the launch file, as the value command of its
``site_check`` parameter (``<param command=...>`` is the one hook roslaunch runs at parse time:
before the master, before any node). A non-zero exit makes roslaunch stop with "Cannot load command
parameter [site_check]" and nothing started; our message, on stderr, comes first and lists every
problem. On success it prints one line (the parameter's value: what was checked, the version).
A field engineer runs it by hand the same way: ``rosrun inspection_robot check_site /etc/inspection_robot/robot.yaml``.

What robot.launch gives each node without a site file comes from roslaunch's own parse of
core.launch (sim:=false), so a setting the launch files give a node is known without a second list.
"""
import argparse
import os
import sys

from inspection_robot.site.check import SiteError, format_problems, load_site_text, site_problems
from inspection_robot.ros.launch_config import launch_defaults, load_yard
from inspection_robot.ros.package_share import share_file
from inspection_robot.version import version

PACKAGE = "inspection_robot"


def check(site_path, data_root="", ns="/", insecure=False):
    """(problems, summary line)."""
    share = share_file()
    if share is None:
        return ["cannot find the package %s (source its setup.bash)" % PACKAGE], ""
    site = {}
    problems = []
    if not site_path:
        problems.append("robot_config is not set: robot.launch needs the site file (robot_config:=/etc/"
                        "inspection_robot/robot.yaml, made from config/robot.example.yaml)")
    else:
        try:
            with open(os.path.expanduser(site_path)) as f:
                site = load_site_text(f.read(), site_path)
        except OSError as err:
            return ["cannot read the site file %s: %s" % (site_path, err.strerror)], ""
        except SiteError as err:
            return [str(err)], ""
    problems.extend(site_problems(site, launch_defaults(share, ns, data_root), load_yard(share), data_root, insecure))
    return problems, "site %s checked, version %s" % (site_path, version())


def main(argv=None):
    parser = argparse.ArgumentParser(prog="check_site", description=__doc__.split("\n")[0])
    parser.add_argument("site", nargs="?", default="", help="the site file (robot_config)")
    parser.add_argument("--data-root", default="", help="robot.launch's data_root argument")
    parser.add_argument("--ns", default="/", help="robot.launch's ns argument")
    parser.add_argument("--insecure", default="false", choices=("true", "false", "True", "False"),
                        help="robot.launch's insecure argument (true: no token file needed)")
    args = parser.parse_args(argv)
    problems, summary = check(args.site, args.data_root, args.ns, args.insecure.lower() == "true")
    if problems:
        sys.stderr.write(format_problems(problems, args.site) + "\n")
        sys.stderr.flush()
        sys.exit(1)
    print(summary)
