#!/usr/bin/env python3
"""file_control read path: throughput of fetching a large file in chunks through the command
table (JSON + base64, what the service answers), and the memory one read request needs, which
must stay bounded by the chunk size whatever the file's size; calibration_control: how long the
probe's 40,000-target upload and the largest accepted one (64 pointers) hold it, and how many
loads of a preset mix two calibrations while uploads swap it; the capture quota's walk and check.
One JSON line per figure."""
import json
import os
import shutil
import tempfile
import threading
import time
import tracemalloc

import cv2
import numpy as np

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.data_layout import CaptureQuota, tree_bytes
from inspection_robot.files import write_atomic
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.preset import PresetError, PresetInfo, load_preset
from inspection_robot.storage.commands import DEFAULT_MAX_CHUNK_BYTES, FileCommands

FILE_MB = 32


def fetch(files, path):
    offset, started = 0, time.perf_counter()
    while True:
        reply = files.table.dispatch("read", json.dumps({"path": path, "offset": offset}))
        chunk = json.loads(reply.data)
        offset += chunk["length"]
        if chunk["eof"]:
            return offset, time.perf_counter() - started


def main():
    root = tempfile.mkdtemp(prefix="bench_files_")
    try:
        os.makedirs(os.path.join(root, "captures"))
        for size_mb in (1, FILE_MB):
            with open(os.path.join(root, "captures", "f%d.bin" % size_mb), "wb") as f:
                f.write(os.urandom(size_mb << 20))
        files = FileCommands(root, ["captures"], DEFAULT_MAX_CHUNK_BYTES)
        size, seconds = fetch(files, "captures/f%d.bin" % FILE_MB)
        print(json.dumps({"bench": "files_read_throughput", "file_mb": FILE_MB,
                          "chunk_bytes": DEFAULT_MAX_CHUNK_BYTES, "mb_per_s": round(size / seconds / 1e6, 1)}))
        peaks = {}
        for size_mb in (1, FILE_MB):
            tracemalloc.start()
            files.table.dispatch("read", json.dumps({"path": "captures/f%d.bin" % size_mb, "offset": 0}))
            peaks[size_mb] = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        print(json.dumps({"bench": "files_read_peak_memory", "chunk_bytes": DEFAULT_MAX_CHUNK_BYTES,
                          "peak_kb_1mb_file": peaks[1] // 1024,
                          "peak_kb_%dmb_file" % FILE_MB: peaks[FILE_MB] // 1024}))
    finally:
        shutil.rmtree(root, ignore_errors=True)
    calibration_figures()
    quota_figures()
    return 0


PRESET = "presets/p1/20260101_120000"
POINTER = {"kind": "pointer", "box": [100, 100, 200, 100, 200, 200, 100, 200], "start_angle": -135,
           "end_angle": 135, "start_value": 0, "end_value": 1.6}


def _lamps(prefix, count, left):
    return [{"kind": "lamp", "colour": "red", "name": "%s_%d" % (prefix, i),
             "box": [left + 10 * i, 100, left + 100 + 10 * i, 100, left + 100 + 10 * i, 200, left + 10 * i, 200]}
            for i in range(count)]


def calibration_figures(loads=4000):
    root = tempfile.mkdtemp(prefix="bench_calibration_")
    try:
        preset = os.path.join(root, PRESET)
        info = PresetInfo("p1", "visible", False, "20260101_120000", 0.0, 0.0, 1.0, 0x4000, (0.0, 0.0, 0.0),
                          [1.0, 2.0], 640, 360)
        write_atomic(os.path.join(preset, "preset.ini"), info.to_ini())
        picture = np.random.RandomState(0).randint(0, 255, (360, 640, 3)).astype(np.uint8)
        cv2.imwrite(os.path.join(preset, "zoom0.jpg"), picture)
        commands = CalibrationCommands(root, ["presets"], ["presets"],
                                       ZoomOptics([[1.0, 59.8], [2.0, 31.6], [4.0, 16.2]], 640, 360))

        def upload(targets):
            data = json.dumps({"preset": PRESET, "targets": targets})
            started = time.perf_counter()
            reply = commands.table.dispatch("upload", data)
            return reply.ack, time.perf_counter() - started
        for count in (40000, 64):
            ack, seconds = upload([POINTER] * count)
            print(json.dumps({"bench": "calibration_upload_hold", "pointer_targets": count, "ack": ack,
                              "s": round(seconds, 3)}))
        for same_count in (False, True):
            one, other = (_lamps("a", 3, 100), _lamps("b", 3, 300)) if same_count else \
                (_lamps("a", 1, 100), _lamps("b", 3, 300))
            whole = dict((tuple(t["name"] for t in ts), [float(t["box"][0]) for t in ts]) for ts in (one, other))
            upload(one)
            stop, uploads = threading.Event(), [0]

            def swap():
                while not stop.is_set():
                    upload(other if uploads[0] % 2 else one)
                    uploads[0] += 1
            writer = threading.Thread(target=swap)
            writer.start()
            mixed = failed = 0
            for _ in range(loads):
                try:
                    loaded = load_preset(preset)
                except PresetError:
                    failed += 1
                    continue
                names = tuple(t.name for t in loaded.targets)
                mixed += whole.get(names) != [float(t.boxes[0][0][0]) for t in loaded.targets]
            stop.set()
            writer.join()
            print(json.dumps({"bench": "preset_snapshot_mixes", "equal_target_counts": same_count, "loads": loads,
                              "uploads": uploads[0], "mixed": mixed, "failed": failed}))
    finally:
        shutil.rmtree(root, ignore_errors=True)


def quota_figures():
    root = tempfile.mkdtemp(prefix="bench_quota_")
    try:
        made = 0
        for files in (7000, 70000):
            for i in range(made, files):
                folder = os.path.join(root, "day%03d" % (i // 500))
                os.makedirs(folder, exist_ok=True)
                with open(os.path.join(folder, "c%06d.jpg" % i), "wb") as f:
                    f.write(b"x")
            made = files
            started = time.perf_counter()
            tree_bytes(root)
            walk_s = time.perf_counter() - started
            quota = CaptureQuota([root], 1 << 40)
            quota.used()
            started = time.perf_counter()
            for _ in range(1000):
                quota.check(300000)
                quota.add(300000)
            print(json.dumps({"bench": "capture_quota", "files": files, "walk_ms": round(walk_s * 1000, 1),
                              "counted_check_us": round((time.perf_counter() - started) * 1000, 2)}))
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
