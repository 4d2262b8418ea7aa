"""Occupancy maps in map_server format (YAML + PGM) and map <-> cell conversions.

A map is a 2-D array of occupancy values in ROS convention (0 free, 100 occupied, -1 unknown),
row 0 at the map origin's y (i.e. already flipped from the image, whose first row is the top),
plus a resolution (m/cell) and the world pose of cell (0, 0)'s corner (x, y, yaw; yaw must be 0).
"""
import math
import os

import numpy as np
import yaml

OCC_FREE = 0
OCC_OCCUPIED = 100
OCC_UNKNOWN = -1


class MapError(Exception):
    """A map file that cannot be read or is inconsistent."""


class GridMap(object):
    def __init__(self, occupancy, resolution, origin):
        occupancy = np.asarray(occupancy, dtype=np.int8)
        if occupancy.ndim != 2 or occupancy.size == 0:
            raise MapError("occupancy must be a non-empty 2-D array")
        if not (resolution > 0 and math.isfinite(resolution)):
            raise MapError("resolution must be a positive number, got %r" % (resolution,))
        if len(origin) < 2:
            raise MapError("origin must be [x, y, yaw]")
        if len(origin) > 2 and abs(float(origin[2])) > 1e-9:
            raise MapError("rotated map origins are not supported (yaw %r)" % (origin[2],))
        self.occupancy = occupancy
        self.resolution = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]), 0.0)

    @property
    def height(self):
        return self.occupancy.shape[0]

    @property
    def width(self):
        return self.occupancy.shape[1]

    def world_to_cell(self, x, y):
        """Return (row, col) of the cell containing map point (x, y) (may lie outside the map)."""
        col = int(math.floor((x - self.origin[0]) / self.resolution))
        row = int(math.floor((y - self.origin[1]) / self.resolution))
        return row, col

    def cell_to_world(self, row, col):
        """Centre of cell (row, col) in map metres; works on NumPy arrays too."""
        return (self.origin[0] + (np.asarray(col) + 0.5) * self.resolution,
                self.origin[1] + (np.asarray(row) + 0.5) * self.resolution)

    def contains(self, row, col):
        return 0 <= row < self.height and 0 <= col < self.width


def load_map(yaml_path):
    """Load a map_server YAML (+ its image) into a GridMap. Raises MapError with the reason."""
    try:
        with open(yaml_path) as f:
            meta = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as err:
        raise MapError("cannot read map %s: %s" % (yaml_path, err))
    if not isinstance(meta, dict):
        raise MapError("map %s is not a YAML mapping" % yaml_path)
    try:
        image = meta["image"]
        resolution = float(meta["resolution"])
        origin = [float(v) for v in meta["origin"]]
        negate = int(meta.get("negate", 0))
        occupied_thresh = float(meta.get("occupied_thresh", 0.65))
        free_thresh = float(meta.get("free_thresh", 0.196))
        mode = str(meta.get("mode", "trinary"))
    except (KeyError, TypeError, ValueError) as err:
        raise MapError("map %s: bad or missing field: %s" % (yaml_path, err))
    if mode not in ("trinary", "scale"):
        raise MapError("map %s: mode %r not supported (trinary|scale)" % (yaml_path, mode))
    if not os.path.isabs(image):
        image = os.path.join(os.path.dirname(os.path.abspath(yaml_path)), image)
    pixels = read_pgm(image)
    # map_server: p = (255 - value) / 255 is the occupancy probability (negate flips it).
    p = pixels.astype(np.float32) / 255.0 if negate else (255.0 - pixels.astype(np.float32)) / 255.0
    occupancy = np.full(pixels.shape, OCC_UNKNOWN, dtype=np.int8)
    occupancy[p > occupied_thresh] = OCC_OCCUPIED
    occupancy[p < free_thresh] = OCC_FREE
    if mode == "scale":
        between = (p >= free_thresh) & (p <= occupied_thresh)
        scaled = 99.0 * (p - free_thresh) / (occupied_thresh - free_thresh)
        occupancy[between] = scaled[between].astype(np.int8)
    return GridMap(np.flipud(occupancy), resolution, origin)


def save_map(grid, yaml_path, image_name=None):
    """Write ``grid`` as map_server YAML + binary PGM (trinary: 0 black, 254 white, 205 unknown)."""
    image_name = image_name or os.path.splitext(os.path.basename(yaml_path))[0] + ".pgm"
    pixels = np.full(grid.occupancy.shape, 205, dtype=np.uint8)
    pixels[grid.occupancy == OCC_FREE] = 254
    pixels[grid.occupancy >= 65] = 0
    write_pgm(os.path.join(os.path.dirname(os.path.abspath(yaml_path)), image_name), np.flipud(pixels))
    meta = {"image": image_name, "resolution": grid.resolution,
            "origin": [grid.origin[0], grid.origin[1], 0.0],
            "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
    with open(yaml_path, "w") as f:
        yaml.safe_dump(meta, f, default_flow_style=None)


def read_pgm(path):
    """Read a binary (P5) or ASCII (P2) 8-bit PGM into a uint8 array (first row = top of image)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as err:
        raise MapError("cannot read map image %s: %s" % (path, err))
    tokens, pos = [], 0
    while len(tokens) < 4:
        while pos < len(raw) and raw[pos:pos + 1].isspace():
            pos += 1
        if raw[pos:pos + 1] == b"#":
            pos = raw.find(b"\n", pos) + 1 or len(raw)
            continue
        start = pos
        while pos < len(raw) and not raw[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            raise MapError("truncated PGM header in %s" % path)
        tokens.append(raw[start:pos])
    magic = tokens[0]
    try:
        width, height, maxval = int(tokens[1]), int(tokens[2]), int(tokens[3])
    except ValueError:
        raise MapError("bad PGM header in %s" % path)
    if maxval != 255 or magic not in (b"P5", b"P2"):
        raise MapError("only 8-bit P5/P2 PGM supported (%s: %r, maxval %d)" % (path, magic, maxval))
    if magic == b"P5":
        body = np.frombuffer(raw, dtype=np.uint8, count=width * height, offset=pos + 1) \
            if len(raw) >= pos + 1 + width * height else None
    else:
        values = raw[pos:].split()
        body = np.array([int(v) for v in values[:width * height]], dtype=np.uint8) \
            if len(values) >= width * height else None
    if body is None:
        raise MapError("PGM %s shorter than %dx%d" % (path, width, height))
    return body.reshape(height, width).copy()


def write_pgm(path, pixels):
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    with open(path, "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (pixels.shape[1], pixels.shape[0]))
        f.write(pixels.tobytes())
