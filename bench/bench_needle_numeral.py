"""Benchmark: pointer readings with the needle over a numeral and its major tick.

Why: a needle crossing a numeral of its own ink (the simulated yard's transformer_1/oil_level at 6,
patrol_sim: 0.56 % FS, one reading in ~400) is the reader's worst case, and the general benches
rarely place a needle there. Each case puts the needle within +-``OFFSET_DEG`` of a numbered major
tick (an interior one, drawn right over its numeral) and reads it in the true box jittered by
about a finder's error:

- world: a gauge of the simulated yard (config/sim_world.yaml) through the camera team's renderer
  from 2.5..4 m, a little off its axis, calibrated from the ground truth (sim world_specs);
- synthetic: a gauge of a random fixture style (inspection_robot_testing.fixtures) in a random
  perspective on a textured wall, lighting, blur and noise as bench_inspection's synthetic part.

The split, fixed before any tuning: case seeds 0..TUNE_CASES-1 are the tuning part (thresholds of
the needle fit are chosen on it only), seeds 1000..1000+TEST_CASES-1 the test part (the figures
that count). ``BENCH_NUMERAL_PART`` = tuning | test | both (default both). Prints one JSON line per
part and kind: n, worst and p99 error (% FS), share over 0.5 % FS, time per read.
"""
import json
import math
import os
import sys
import time

import cv2
import numpy as np

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.pointer import PointerReader
from inspection_robot.inspection.readers import ReadFailed

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TUNE_CASES = int(os.environ.get("BENCH_NUMERAL_TUNE_CASES", "150"))
TEST_CASES = int(os.environ.get("BENCH_NUMERAL_TEST_CASES", "300"))
TEST_SEED0 = 1000
OFFSET_DEG = 4.0       # the needle within this of a numbered major tick: over its numeral
BOX_JITTER_PX = 0.0    # sigma of the box corners' error (px); 0: the true box, so the figure is the needle fit's own
LIMIT_PCT_FS = 0.5     # patrol_sim's GAUGE_LIMIT_PCT_FS


def _over_numeral(rng, scale, majors):
    """A value whose needle lies within OFFSET_DEG of an interior numbered major tick."""
    j = int(rng.integers(1, majors - 1))
    tick = scale.start_value + (scale.end_value - scale.start_value) * j / float(majors - 1)
    per_deg = (scale.end_value - scale.start_value) / scale.sweep
    return tick + float(rng.uniform(-OFFSET_DEG, OFFSET_DEG)) * per_deg


def _jitter(rng, quad):
    return np.asarray(quad, float) + rng.normal(0.0, BOX_JITTER_PX, (4, 2))


class WorldCases(object):
    """The simulated yard's gauges rendered with the needle over a numeral."""

    def __init__(self):
        import yaml
        from inspection_robot.camera.optics import ZoomOptics
        from inspection_robot.sim.render import Renderer
        from inspection_robot.sim.world import World
        self.world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
        table = yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))["camera_optics"]
        self.width, self.height = 1280, 720
        self.optics = ZoomOptics(table["zoom_hfov_deg"], self.width, self.height)
        self.renderer = Renderer(self.world, seed=1)
        self.gauges = sorted((f for f in self.world.faces.values() if f.type == "gauge"), key=lambda f: f.id)

    def case(self, seed):
        from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
        rng = np.random.default_rng(seed)
        world, face = self.world, self.gauges[seed % len(self.gauges)]
        normal = face.quad.normal
        dist = float(rng.uniform(2.5, 4.0))
        side = np.array([-normal[1], normal[0], 0.0]) * float(rng.uniform(-0.4, 0.4))
        spot = face.quad.centre + normal * dist + side
        to_face = face.quad.centre - spot
        pose = (spot[0], spot[1], math.atan2(to_face[1], to_face[0]))
        tilt = math.degrees(math.atan2(world.sensor_height - face.quad.centre[2], np.hypot(to_face[0], to_face[1])))
        share = float(rng.uniform(0.12, 0.3))     # the face's width as a share of the picture's
        zoom = share * self.width * dist / (self.optics.focal_px(1.0, self.width) * face.quad.width)
        head = RenderedHead(self.renderer, self.optics, pose, world.sensor_height, self.width, self.height)
        head.set_angles(float(rng.uniform(-1.5, 1.5)), tilt + float(rng.uniform(-1.0, 1.0)))
        head.set_zoom(max(1.0, min(30.0, zoom)))
        scale = GaugeScale(face.start_angle, face.end_angle, face.range[0], face.range[1])
        value = min(max(_over_numeral(rng, scale, face.major_ticks), face.range[0]), face.range[1])
        face.set_value(value)
        image = self.renderer.render(head.camera(), frame_index=seed)
        specs = [s for s in world_specs(world, head) if s["name"] == face.id]
        if not specs:
            return None
        spec = specs[0]
        quad = _jitter(rng, np.asarray(spec["box"], float).reshape(4, 2))
        return face.id, image, quad, scale, value, (spec["centre"], spec["radius"], spec["aspect"])


def synthetic_case(seed):
    """A fixture gauge of a random style with the needle over a numeral, in a random perspective."""
    rng = np.random.default_rng(seed)
    style = sorted(S.GAUGE_STYLES)[int(rng.integers(0, len(S.GAUGE_STYLES)))]
    low = float(rng.choice([0.0, -0.1, 0.0, -20.0]))
    high = low + float(rng.choice([1.0, 1.6, 2.5, 160.0]))
    scale = S.style_scale(style, low, high)
    value = _over_numeral(rng, scale, 11)     # draw_gauge_face's default: 10 intervals, 11 numbered ticks
    w, h = 640, 360
    scene = S.textured_background(w, h, rng)
    true_quad = S.perspective_quad((w / 2.0 + rng.uniform(-100, 100), h / 2.0 + rng.uniform(-40, 40)),
                                   float(rng.uniform(110, 220)), rng.uniform(-30, 30), rng.uniform(-20, 20),
                                   rng.uniform(-8, 8))
    S.paste(scene, S.draw_gauge_face(scale, value, 400, style), true_quad)
    c = true_quad.mean(axis=0)
    size = np.ptp(true_quad[:, 0])
    glare = (c[0] + rng.uniform(-0.3, 0.3) * size, c[1] + rng.uniform(-0.3, 0.3) * size, size * 0.08) \
        if rng.random() < 0.3 else None
    scene = S.degrade(scene, rng, noise=float(rng.uniform(1, 5)), blur=float(rng.uniform(0, 1.2)),
                      gain=float(rng.uniform(0.55, 1.35)), offset=float(rng.uniform(-15, 15)), glare=glare)
    return style, scene, _jitter(rng, true_quad), scale, value, ((0.5, 0.5), 0.45, 1.0)


def run(kind, seeds, make, reader, verbose):
    errors, times, refused = [], [], 0
    for seed in seeds:
        case = make(seed)
        if case is None:
            continue
        name, image, quad, scale, value, (centre, radius, aspect) = case
        t0 = time.perf_counter()
        try:
            reading = reader.read(image, quad, scale, centre, radius, aspect)
        except ReadFailed:
            refused += 1
            continue
        times.append(time.perf_counter() - t0)
        error = scale.error_percent_fs(reading.value, value)
        errors.append(error)
        if verbose:
            print(json.dumps({"seed": seed, "kind": kind, "name": name, "value": round(value, 5),
                              "read": round(reading.value, 5), "error_pct_fs": round(error, 4),
                              "confidence": round(reading.confidence, 1)}))
    return errors, times, refused


def report(name, errors, times, refused):
    e = np.array(errors)
    print(json.dumps({"bench": name, "n": len(e), "refused": refused,
                      "worst_pct_fs": round(float(e.max()), 3) if len(e) else None,
                      "p99_pct_fs": round(float(np.percentile(e, 99)), 3) if len(e) else None,
                      "mean_pct_fs": round(float(e.mean()), 3) if len(e) else None,
                      "over_limit": int((e > LIMIT_PCT_FS).sum()),
                      "read_p50_ms": round(1000 * float(np.median(times)), 1) if times else None}))


def main():
    cv2.setNumThreads(1)
    part = os.environ.get("BENCH_NUMERAL_PART", "both")
    verbose = os.environ.get("BENCH_NUMERAL_VERBOSE") == "1"
    parts = []
    if part in ("tuning", "both"):
        parts.append(("tuning", range(TUNE_CASES)))
    if part in ("test", "both"):
        parts.append(("test", range(TEST_SEED0, TEST_SEED0 + TEST_CASES)))
    reader = PointerReader()
    world = WorldCases()
    for label, seeds in parts:
        both = [[], [], 0]
        for kind, make in (("world", world.case), ("synthetic", synthetic_case)):
            errors, times, refused = run(kind, seeds, make, reader, verbose)
            report("needle_numeral_%s_%s" % (label, kind), errors, times, refused)
            both = [both[0] + errors, both[1] + times, both[2] + refused]
        report("needle_numeral_%s" % label, *both)
    return 0


if __name__ == "__main__":
    sys.exit(main())
