#!/usr/bin/env python3
"""file_control read path: throughput of fetching a large file in chunks through the command
table (JSON + base64, what the service answers), and the memory one read request needs, which
must stay bounded by the chunk size whatever the file's size. One JSON line per figure."""
import json
import os
import shutil
import tempfile
import time
import tracemalloc

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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
