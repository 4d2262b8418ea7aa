"""Benchmark: simulated camera render + JPEG encode per 1920x1080 frame, thermal frame time.

Prints one JSON line per figure.
"""
import math
import os
import time

import cv2
import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.camera.optics import focal_for_hfov
from inspection_robot.sim.render import PinholeCamera, Renderer, ThermalRenderer
from inspection_robot.sim.world import World

from benchlib import latency_figures, report

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def report_latencies(name, samples):
    report(bench=name, **latency_figures(samples, digits=2))


def main():
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    table = yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))["camera_optics"]
    optics = ZoomOptics(table["zoom_hfov_deg"], table["width"], table["height"])
    renderer = Renderer(world, seed=1)
    face = world.faces["transformer_1/oil_temp"]
    pose = (face.quad.centre[0], face.quad.centre[1] + 6.0, -math.pi / 2)
    views = [(world.start_pose, 0.0, 0.0, 1.0), (pose, 0.0, -0.05, 4.0), (pose, 0.3, 0.0, 1.0),
             (pose, 0.0, -0.06, 16.0)]
    cameras = [PinholeCamera.from_pose(p, pan, tilt, world.sensor_height, optics.focal_px(z), 1920, 1080)
               for p, pan, tilt, z in views]
    for cam in cameras:   # warm the face texture cache as a running camera would
        renderer.render(cam)
    render, total = [], []
    for i in range(40):
        cam = cameras[i % len(cameras)]
        t0 = time.perf_counter()
        img = renderer.render(cam)
        t1 = time.perf_counter()
        cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
        t2 = time.perf_counter()
        render.append(t1 - t0)
        total.append(t2 - t0)
    report_latencies("camera_render_1080p", render)
    report_latencies("camera_render_jpeg_1080p", total)
    thermal = ThermalRenderer(world, seed=1)
    cams = [PinholeCamera.from_pose(p, pan, tilt, world.sensor_height, focal_for_hfov(384, 25.0), 384, 288)
            for p, pan, tilt, _ in views]
    samples = []
    for i in range(200):
        t0 = time.perf_counter()
        thermal.render(cams[i % len(cams)])
        samples.append(time.perf_counter() - t0)
    report_latencies("thermal_frame_384x288", samples)


if __name__ == "__main__":
    main()
