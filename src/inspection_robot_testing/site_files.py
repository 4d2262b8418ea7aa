"""A site file that passes the site check: config/robot.example.yaml with the files it names made
for real (a map, the token and the thermal camera's password, private), for tests of site.py and of
robot.launch's start-up."""
import os
import stat

import numpy as np

from inspection_robot.nav.gridmap import GridMap, save_map
from inspection_robot.site.check import TEMPLATE, load_site_text

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def private_file(path, text="s3cret\n"):
    """``path`` (str) written with ``text``, mode 600, as the nodes require of a secret file."""
    with open(path, "w") as f:
        f.write(text)
    os.chmod(path, stat.S_IRUSR | stat.S_IWUSR)
    return path


def template_site(folder):
    """The template's settings (a dict keyed by node name) with its map, token and password files in
    ``folder``: the check passes on it as it is; a test changes one setting and sees that one refused."""
    with open(os.path.join(ROOT, TEMPLATE)) as f:
        site = load_site_text(f.read(), TEMPLATE)
    occupancy = np.zeros((40, 60), dtype=np.int8)
    occupancy[10:20, 10:20] = 100
    map_file = os.path.join(folder, "site_map.yaml")
    save_map(GridMap(occupancy, 0.5, (0.0, 0.0, 0.0)), map_file)
    site["move_base"]["map_file"] = map_file
    site["rosbridge_websocket"]["auth_token_file"] = private_file(os.path.join(folder, "token"))
    site["infrared_imager"]["isapi"]["password_file"] = private_file(os.path.join(folder, "thermal_password"))
    return site
