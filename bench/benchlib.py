"""Helpers shared by the benchmarks: a free TCP port, percentiles, one JSON line per figure."""
import json
import socket
import time


def free_port():
    """A TCP port on 127.0.0.1 that was free a moment ago (for a roscore or server to bind)."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    sock.close()
    return port


def percentile(values, q):
    """The nearest-rank ``q`` quantile (0..1) of ``values``; None when there are none."""
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def latency_figures(samples_s, digits=3):
    """p50 / p99 / max in ms and the count of latencies given in seconds (nearest rank)."""
    ms = [value * 1000.0 for value in samples_s]
    return {"p50_ms": round(percentile(ms, 0.5), digits), "p99_ms": round(percentile(ms, 0.99), digits),
            "max_ms": round(max(ms), digits), "n": len(ms)}


def report(**fields):
    """Print one figure as one JSON line (the format every bench/bench_*.py prints)."""
    print(json.dumps(fields), flush=True)


def start_roscore(timeout_s=20.0):
    """A roscore of the bench's own on a free port, ROS_MASTER_URI pointed at it (this process and
    its children); returns its process once the master answers (the caller stops it)."""
    import os
    import subprocess

    import rosgraph
    port = free_port()
    os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % port
    proc = subprocess.Popen(["roscore", "-p", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout_s
    while not rosgraph.is_master_online():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError("roscore did not start")
        time.sleep(0.1)
    return proc


def wait_for(condition, timeout_s, what, period_s=0.02):
    """``condition()``'s first truthy value, polled every ``period_s``; RuntimeError after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise RuntimeError("timed out waiting for %s" % what)
        time.sleep(period_s)
