#!/usr/bin/env python3
"""Writes the sample substation map (config/maps/substation.yaml + .pgm) from config/sim_world.yaml.

Usage: scripts/rosenv python3 scripts/make_sample_map.py [--resolution 0.05] [--out config/maps/substation.yaml]
"""
import argparse
import os
import sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src"))

from inspection_robot.nav.gridmap import save_map  # noqa: E402
from inspection_robot.sim.nav_yard import occupancy_map  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=os.path.join(ROOT, "config", "sim_world.yaml"))
    parser.add_argument("--resolution", type=float, default=0.05)
    parser.add_argument("--out", default=os.path.join(ROOT, "config", "maps", "substation.yaml"))
    args = parser.parse_args()
    with open(args.world) as f:
        world = yaml.safe_load(f)["world"]
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    grid = occupancy_map(world, args.resolution)
    save_map(grid, args.out)
    print("wrote %s (%d x %d cells at %.3f m)" % (args.out, grid.width, grid.height, grid.resolution))


if __name__ == "__main__":
    main()
