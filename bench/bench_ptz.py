"""Benchmark: Pelco-D command round trip through the simulated head's pty, and frame rates.

Prints one JSON line per figure. A pty has no baud rate: a real RS485 line at 9600 baud carries at
most ~137 seven-byte frames/s, far below what the driver sustains here.
"""
import os
import tempfile
import time

from inspection_robot.ptz import pelco
from inspection_robot.ptz.driver import PelcoHead
from inspection_robot.ptz.terrace import Terrace
from inspection_robot.sim.pelco_head import PtyPelcoServer, SimPelcoHead

from benchlib import percentile, report


def main():
    folder = tempfile.mkdtemp(prefix="bench_ptz_")
    link = os.path.join(folder, "pelco")
    server = PtyPelcoServer(SimPelcoHead(position_speed_deg_s=100000.0), link)
    server.plug()
    head = PelcoHead(link, reply_timeout=0.5)
    try:
        if not head.wait_connected(5.0):
            raise SystemExit("driver did not open %s" % link)
        # query round trip (write query, simulator answers, reader hands the reply back)
        n = 1000
        times = []
        for _ in range(n):
            start = time.perf_counter()
            head.query_pan()
            times.append((time.perf_counter() - start) * 1000.0)
        report(bench="ptz_query_roundtrip", p50_ms=round(percentile(times, 0.5), 3),
               p99_ms=round(percentile(times, 0.99), 3), n=n)
        # a whole terrace command: get_angle = two queries, through the command table
        table = Terrace(head, {"high_speed": 63, "mid_speed": 32, "low_speed": 8}, poll_period=0.001).table()
        times = []
        for _ in range(300):
            start = time.perf_counter()
            assert table.dispatch("get_angle", "").ack == "success"
            times.append((time.perf_counter() - start) * 1000.0)
        report(bench="ptz_get_angle_roundtrip", p50_ms=round(percentile(times, 0.5), 3),
               p99_ms=round(percentile(times, 0.99), 3), n=len(times))
        times = []
        for i in range(100):
            start = time.perf_counter()
            assert table.dispatch("set_angle", "%d,%d" % ((i % 2) * 1000, (i % 2) * 500)).ack == "success"
            times.append((time.perf_counter() - start) * 1000.0)
        report(bench="ptz_set_angle_roundtrip_instant_slew", p50_ms=round(percentile(times, 0.5), 3),
               p99_ms=round(percentile(times, 0.99), 3), n=len(times))
        # sustained command frames written (simulator decodes every one)
        before = server.head.frames_handled
        count, start = 0, time.perf_counter()
        while time.perf_counter() - start < 2.0:
            head.move(1, 0, 0x20, 0)
            count += 1
        server_deadline = time.perf_counter() + 2.0
        while server.head.frames_handled - before < count and time.perf_counter() < server_deadline:
            time.sleep(0.01)
        elapsed = time.perf_counter() - start
        report(bench="ptz_frames_written_per_s", frames_per_s=round(count / elapsed, 1), n=count,
               decoded_by_sim=server.head.frames_handled - before)
        # sustained query/reply pairs
        count, start = 0, time.perf_counter()
        while time.perf_counter() - start < 2.0:
            head.query_tilt()
            count += 1
        report(bench="ptz_query_pairs_per_s", pairs_per_s=round(count / (time.perf_counter() - start), 1), n=count)
        # the pure reader alone
        stream = b"".join(pelco.pan_reply(1, i % 36000) for i in range(20000))
        reader = pelco.FrameReader()
        start = time.perf_counter()
        frames = reader.feed(stream)
        report(bench="ptz_reader_frames_per_s", frames_per_s=round(len(frames) / (time.perf_counter() - start)),
               n=len(frames))
    finally:
        head.close()
        server.unplug()
        os.rmdir(folder)


if __name__ == "__main__":
    main()
