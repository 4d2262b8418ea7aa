"""What roslaunch makes of this package's launch files, for the site check (tools/check_site.py):
the parameters core.launch sets without a site file, and the simulated yard's site values."""
import os

from roslaunch.config import ROSLaunchConfig
from roslaunch.substitution_args import resolve_args
from roslaunch.xmlloader import XmlLoader

from inspection_robot.site.check import SIM_SITE_FILE, flatten, load_site_text, sim_yard


def launch_defaults(share, ns, data_root):
    """{``node/key``: value} robot.launch sets without a site file (core.launch sim:=false), relative to ``ns``."""
    config = ROSLaunchConfig()
    # record:=true: bag_recorder's settings are valid in a site file whether robot.launch records or not
    argv = ["sim:=false", "record:=true", "robot_config:=", "ns:=%s" % (ns or "/"), "data_root:=%s" % data_root]
    XmlLoader().load(os.path.join(share, "launch", "core.launch"), config, argv=argv, verbose=False)
    prefix = "/" + (ns or "/").strip("/") + "/" if (ns or "/").strip("/") else "/"
    defaults = {}
    for name, param in config.params.items():
        if name.startswith(prefix):
            defaults[name[len(prefix):]] = param.value
    for name, value in list(defaults.items()):   # roslaunch drops empty mappings; keep them known
        if isinstance(value, dict):
            defaults.update(flatten(value, name + "/"))
    return defaults


def load_yard(share):
    with open(os.path.join(share, SIM_SITE_FILE)) as f:
        sim_site = load_site_text(resolve_args(f.read()), SIM_SITE_FILE)   # $(find ...) as subst_value does
    return sim_yard(sim_site)
