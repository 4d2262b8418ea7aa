"""Benchmark: meter finding and reading accuracy over rendered cases with known truth.

Synthetic part (>= 300 cases): a gauge of a random style on a textured wall, recorded from one
head position, then seen again after a head move (shift, zoom change, roll, slight perspective)
with a new random value, lighting gain/offset, glare, blur, noise and partial occlusion.
find = feature localisation of the box against the reference; read = pointer reading in the
located box. World part: the camera team's renderer and ground-truth projection of the
simulated yard's gauges: record a preset, calibrate it from ground truth, come back off by up to
0.3 m / 5 deg, find with the full finder (heading correction, coarse-to-fine, re-centring), read.

Prints one JSON line per figure: mean abs error (% of full scale), share within 1 % and 1.5 %
FS, find success rate, mean ROI IoU, time per find and per read.
"""
import json
import math
import os
import shutil
import sys
import tempfile
import time

import cv2
import numpy as np

from inspection_robot.sim import fixtures as S
from inspection_robot.inspection.geometry import quad_iou, transform_quad
from inspection_robot.inspection.locate import LocateError, Locator
from inspection_robot.inspection.readers import PointerReader

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 640, 360
CASES = int(os.environ.get("BENCH_INSPECTION_CASES", "320"))


def synthetic_case(rng, locator, reader):
    style = list(S.GAUGE_STYLES)[int(rng.integers(0, len(S.GAUGE_STYLES)))]
    low = float(rng.choice([0.0, -0.1, 0.0, -20.0]))
    high = low + float(rng.choice([1.0, 1.6, 2.5, 160.0]))
    scale = S.style_scale(style, low, high)
    wall = S.textured_background(1400, 900, rng)
    side = float(rng.uniform(90, 170))
    quad_wall = S.perspective_quad((700 + rng.uniform(-60, 60), 450 + rng.uniform(-40, 40)), side,
                                   rng.uniform(-35, 35), rng.uniform(-25, 25), rng.uniform(-8, 8))
    ref_matrix = np.array([[1.0, 0, W / 2.0 - 700], [0, 1.0, H / 2.0 - 450], [0, 0, 1]])
    ref = cv2.warpPerspective(wall, ref_matrix, (W, H), flags=cv2.INTER_AREA)
    ref_quad = transform_quad(ref_matrix, quad_wall)
    S.paste(ref, S.draw_gauge_face(scale, rng.uniform(low, high), 400, style), ref_quad)
    # the head comes back a little off: shift, zoom, roll, a touch of perspective
    z = float(rng.uniform(0.8, 1.3))
    a = math.radians(rng.uniform(-3, 3))
    move = np.array([[z * math.cos(a), -z * math.sin(a), 0], [z * math.sin(a), z * math.cos(a), 0],
                     [rng.uniform(-4e-5, 4e-5), rng.uniform(-4e-5, 4e-5), 1.0]])
    centre = np.array([[1, 0, -W / 2.0], [0, 1, -H / 2.0], [0, 0, 1]])
    move = np.linalg.inv(centre).dot(move).dot(centre)
    move[:2, 2] += rng.uniform(-50, 50, 2)
    new_matrix = move.dot(ref_matrix)
    value = float(rng.uniform(low, high))
    new = cv2.warpPerspective(wall, new_matrix, (W, H), flags=cv2.INTER_AREA)
    true_quad = transform_quad(new_matrix, quad_wall)
    S.paste(new, S.draw_gauge_face(scale, value, 400, style), true_quad)
    c = true_quad.mean(axis=0)
    size = np.ptp(true_quad[:, 0])
    glare = (c[0] + rng.uniform(-0.3, 0.3) * size, c[1] + rng.uniform(-0.3, 0.3) * size, size * 0.08) \
        if rng.random() < 0.3 else None
    occlusion = None
    if rng.random() < 0.2:  # a cable or branch across a corner of the box
        corner = true_quad[int(rng.integers(0, 4))]
        d = (c - corner) * 0.35
        occlusion = [corner - [4, 0], corner + [4, 0], corner + d + [4, 0], corner + d - [4, 0]]
    new = S.degrade(new, rng, noise=float(rng.uniform(1, 5)), blur=float(rng.uniform(0, 1.2)),
                    gain=float(rng.uniform(0.55, 1.35)), offset=float(rng.uniform(-15, 15)), glare=glare,
                    occlusion=occlusion)
    ref_features = locator.features(ref)
    t0 = time.perf_counter()
    try:
        located = locator.locate(ref_features, new, [ref_quad])
    except LocateError:
        return None, time.perf_counter() - t0, None, 0.0
    t_find = time.perf_counter() - t0
    iou = quad_iou(located.quads[0], true_quad)
    t0 = time.perf_counter()
    reading = reader.read(new, located.quads[0], scale)
    t_read = time.perf_counter() - t0
    return scale.error_percent_fs(reading.value, value), t_find, t_read, iou


def world_cases(rng, locator, reader, count, tmp):
    """The simulated yard's gauges through the real renderer and the full finder: record a preset,
    calibrate it from ground truth, change the value, come back off by up to 0.3 m / 5 deg, find
    (heading correction, coarse-to-fine, re-centring), read."""
    import yaml
    from inspection_robot.camera.optics import ZoomOptics
    from inspection_robot.inspection.calibration import calibrate
    from inspection_robot.inspection.finder import Finder, FindError
    from inspection_robot.inspection.geometry import quads_from_flat
    from inspection_robot.inspection.preset import load_preset
    from inspection_robot.inspection.recorder import record_preset
    from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
    from inspection_robot.sim.render import Renderer, ground_truth
    from inspection_robot.sim.world import World
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    table = yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))["camera_optics"]
    width, height = 800, 450
    optics = ZoomOptics(table["zoom_hfov_deg"], width, height)
    renderer = Renderer(world, seed=1)
    gauges = [f for f in world.faces.values() if f.type == "gauge"]
    out = []
    for i in range(count):
        face = gauges[i % len(gauges)]
        normal = face.quad.normal
        dist = float(rng.uniform(2.5, 4.0))
        spot = face.quad.centre + normal * dist
        pose = (spot[0], spot[1], math.atan2(-normal[1], -normal[0]))
        tilt = math.degrees(math.atan2(world.sensor_height - face.quad.centre[2], dist))
        zoom = max(1.0, min(30.0, 0.3 * width * dist / (optics.focal_px(1.0, width) * face.quad.width)))
        head = RenderedHead(renderer, optics, pose, world.sensor_height, width, height)
        head.set_angles(0.0, tilt)
        head.set_zoom(zoom)
        low, high = face.range
        face.set_value(float(rng.uniform(low, high)))
        state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": zoom, "pose": pose}
        path = record_preset(head, tmp, "case%03d" % i, "20260101_000000", state, min_zoom=optics.min_zoom)
        specs = [s for s in world_specs(world, head) if s["name"] == face.id]
        if not specs:
            out.append((None, 0.0, None, 0.0))
            continue
        calibrate(path, specs, optics)
        preset = load_preset(path)
        value = float(rng.uniform(low, high))
        face.set_value(value)
        dx, dy = rng.uniform(-0.3, 0.3, 2)
        back = (pose[0] + dx, pose[1] + dy, pose[2] + math.radians(rng.uniform(-5, 5)))
        head.pose = back
        finder = Finder(head, optics, locator, os.path.join(tmp, "pictures"), max_moves=3)
        t0 = time.perf_counter()
        try:
            found = finder.find(preset, "find_scale", math.degrees(pose[2] - back[2]), "20260102_000000",
                                cv2.imread)
        except FindError:
            out.append((None, time.perf_counter() - t0, None, 0.0))
            continue
        t_find = time.perf_counter() - t0
        quad = quads_from_flat(found.roi_vertex)[0]
        truth = ground_truth(world, head.camera())["faces"][face.id]
        image = cv2.imread(found.filename)
        p = preset.targets[0].params
        t0 = time.perf_counter()
        reading = reader.read(image, quad, preset.targets[0].scale, p["centre"], p["radius"], p["aspect"])
        t_read = time.perf_counter() - t0
        out.append((preset.targets[0].scale.error_percent_fs(reading.value, value), t_find, t_read,
                    quad_iou(quad, np.array(truth["corners"]))))
    return out


def report(name, results):
    errors = np.array([r[0] for r in results if r[0] is not None])
    finds = [r for r in results if r[0] is not None]
    figures = {"bench": name + "_accuracy", "n": len(results),
               "mean_abs_error_pct_fs": round(float(errors.mean()), 3) if len(errors) else None,
               "within_1pct_fs": round(float((errors <= 1.0).mean()), 4) if len(errors) else None,
               "within_1_5pct_fs": round(float((errors <= 1.5).mean()), 4) if len(errors) else None,
               "p99_error_pct_fs": round(float(np.percentile(errors, 99)), 3) if len(errors) else None}
    print(json.dumps(figures))
    print(json.dumps({"bench": name + "_find", "n": len(results),
                      "success_rate": round(len(finds) / float(len(results)), 4),
                      "mean_roi_iou": round(float(np.mean([r[3] for r in finds])), 4) if finds else None,
                      "p50_ms": round(1000 * float(np.median([r[1] for r in results])), 1)}))
    if finds:
        print(json.dumps({"bench": name + "_read", "n": len(finds),
                          "p50_ms": round(1000 * float(np.median([r[2] for r in finds])), 1),
                          "p99_ms": round(1000 * float(np.percentile([r[2] for r in finds], 99)), 1)}))


def main():
    cv2.setNumThreads(1)
    rng = np.random.default_rng(2024)
    locator = Locator("orb", max_side=960)
    reader = PointerReader()
    report("inspection_synthetic", [synthetic_case(rng, locator, reader) for _ in range(CASES)])
    world_count = int(os.environ.get("BENCH_INSPECTION_WORLD_CASES", "40"))
    if world_count > 0:
        tmp = tempfile.mkdtemp(prefix="bench_inspection_")
        try:
            report("inspection_world", world_cases(rng, locator, reader, world_count, tmp))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
