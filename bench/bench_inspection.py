"""Benchmark: meter finding and reading accuracy over rendered cases with known truth.

Synthetic part (>= 300 cases): a gauge of a random style on a textured wall, recorded from one
head position, then seen again after a head move (shift, zoom change, roll, slight perspective)
with a new random value, lighting gain/offset, glare, blur, noise and partial occlusion.
find = feature localisation of the box against the reference; read = pointer reading in the
located box. World part: the camera team's renderer and ground-truth projection of the
simulated yard's gauges, from a recorded pose and from a pose off by up to 0.3 m / 5 deg.

Prints one JSON line per figure: mean abs error (% of full scale), share within 1 % and 1.5 %
FS, find success rate, mean ROI IoU, time per find and per read.
"""
import json
import math
import os
import sys
import time

import cv2
import numpy as np

from inspection_robot.inspection import synthetic as S
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


def world_cases(rng, locator, reader, count):
    """Gauges of the simulated yard through the real renderer, from a recorded and a perturbed pose."""
    import yaml
    from inspection_robot.camera.optics import ZoomOptics
    from inspection_robot.inspection.gauge import GaugeScale
    from inspection_robot.sim.render import PinholeCamera, Renderer, ground_truth
    from inspection_robot.sim.world import World
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    table = yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))["camera_optics"]
    optics = ZoomOptics(table["zoom_hfov_deg"], table["width"], table["height"])
    renderer = Renderer(world, seed=1)
    width, height = 960, 540
    gauges = [f for f in world.faces.values() if f.type == "gauge"]
    out = []
    for i in range(count):
        face = gauges[i % len(gauges)]
        normal = face.quad.normal
        dist = float(rng.uniform(2.5, 4.0))
        spot = face.quad.centre + normal * dist
        yaw = math.atan2(-normal[1], -normal[0])
        pose = (spot[0], spot[1], yaw)
        tilt = math.atan2(1.2 - face.quad.centre[2], dist)
        zoom = max(1.0, min(30.0, 0.35 * width / (optics.focal_px(1.0, width) * face.quad.width / dist)))
        focal = optics.focal_px(zoom, width)
        cam_ref = PinholeCamera.from_pose(pose, 0.0, tilt, 1.2, focal, width, height)
        low, high = face.range
        face.set_value(float(rng.uniform(low, high)))
        ref = renderer.render(cam_ref)
        truth_ref = ground_truth(world, cam_ref)["faces"][face.id]
        value = float(rng.uniform(low, high))
        face.set_value(value)
        # coming back: pose off by up to 0.3 m / 5 deg, the head re-aimed at the recorded direction
        dx, dy = rng.uniform(-0.3, 0.3, 2)
        dyaw = math.radians(rng.uniform(-5, 5))
        pose2 = (pose[0] + dx, pose[1] + dy, yaw + dyaw)
        cam_new = PinholeCamera.from_pose(pose2, -dyaw + math.radians(rng.uniform(-0.5, 0.5)), tilt, 1.2, focal,
                                          width, height)
        new = renderer.render(cam_new)
        truth = ground_truth(world, cam_new)["faces"][face.id]
        if not truth["in_picture"]:
            out.append((None, 0.0, None, 0.0))
            continue
        fx, fy, radius_m = face.dial_layout()
        scale = GaugeScale(face.start_angle, face.end_angle, low, high)
        t0 = time.perf_counter()
        try:
            located = locator.locate(ref, new, [np.array(truth_ref["corners"])])
        except LocateError:
            out.append((None, time.perf_counter() - t0, None, 0.0))
            continue
        t_find = time.perf_counter() - t0
        t0 = time.perf_counter()
        reading = reader.read(new, located.quads[0], scale, (fx, fy), radius_m / face.quad.width,
                              face.quad.width / face.quad.height)
        t_read = time.perf_counter() - t0
        out.append((scale.error_percent_fs(reading.value, value), t_find, t_read,
                    quad_iou(located.quads[0], np.array(truth["corners"]))))
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
        report("inspection_world", world_cases(rng, locator, reader, world_count))
    return 0


if __name__ == "__main__":
    sys.exit(main())
