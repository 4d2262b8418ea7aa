"""Opt-in stage timings of the echo path through the bridge (a diagnostic for its tail latency).

Off unless the environment names a topic: ``INSPECTION_BRIDGE_TRACE=/bench/echo`` (and
``INSPECTION_BRIDGE_TRACE_FILE``, default /tmp/bridge_trace.json, written at shutdown). Off, each
hook is one attribute test (``if trace.ON``). On, one echo at a time is followed (the bench's raw
round trip has one in flight) with time.perf_counter, through the stages :data:`STAGES` name, and
every garbage collection's pause is recorded (gc.callbacks), so a slow sample can be told apart as
GC, a thread hand-off (GIL or scheduler) or work.
"""
import gc
import json
import os
import threading
import time

TOPIC = os.environ.get("INSPECTION_BRIDGE_TRACE") or None
ON = TOPIC is not None
FILE = os.environ.get("INSPECTION_BRIDGE_TRACE_FILE") or "/tmp/bridge_trace.json"

# stage name -> where it is stamped (the thread in brackets)
STAGES = (
    ("read", "BridgeHandler.on_message entry: frame read and unmasked by tornado [loop]"),
    ("decoded", "RosBackend.publish entry: JSON parsed, op dispatched [loop]"),
    ("published", "message converted, written to the subscriber's socket by the TCPROS publisher [loop]"),
    ("callback", "RosBackend._on_message entry: rospy's receive thread deserialized it [rospy]"),
    ("posted", "encoded to JSON, handed to LoopPoster [rospy]"),
    ("delivered", "RosBackend._deliver entry: the loop ran the posted callback [loop]"),
    ("written", "write_frames returned: the frame handed to the socket [loop]"),
)
NAMES = tuple(name for name, _where in STAGES)

_lock = threading.Lock()
_current = {}
samples = []      # dicts stage -> perf_counter time, complete echoes only
gc_pauses = []    # (start, seconds, generation)
_gc_start = [0.0]


def mark(stage):
    """Stamp ``stage`` of the echo in flight; "read" starts a new one, "written" completes it."""
    now = time.perf_counter()
    with _lock:
        if stage == "read":
            _current.clear()
        elif "read" not in _current or stage in _current:
            return
        _current[stage] = now
        if stage == "written" and len(_current) == len(NAMES):
            samples.append(dict(_current))
            _current.clear()


def _on_gc(phase, info):
    if phase == "start":
        _gc_start[0] = time.perf_counter()
    else:
        gc_pauses.append((_gc_start[0], time.perf_counter() - _gc_start[0], info.get("generation")))


def summary(rows=None, pauses=None):
    """Per stage p50 / p99 / max (ms) of the steps between consecutive stages, and the total; the
    GC pauses that fell inside an echo; the slowest echoes' steps."""
    rows = samples if rows is None else rows
    pauses = gc_pauses if pauses is None else pauses

    def stats(values):
        values = sorted(values)
        if not values:
            return {}
        return {"p50_ms": round(values[len(values) // 2] * 1e3, 3),
                "p99_ms": round(values[min(len(values) - 1, int(len(values) * 0.99))] * 1e3, 3),
                "max_ms": round(values[-1] * 1e3, 3), "mean_ms": round(sum(values) / len(values) * 1e3, 4)}
    steps = {}
    for before, after in zip(NAMES, NAMES[1:]):
        steps["%s->%s" % (before, after)] = stats([row[after] - row[before] for row in rows])
    totals = [row["written"] - row["read"] for row in rows]
    inside = [p for p in pauses if any(row["read"] <= p[0] <= row["written"] for row in rows)]
    slowest = sorted(rows, key=lambda row: row["written"] - row["read"])[-10:]
    return {"n": len(rows), "total": stats(totals), "steps": steps,
            "gc_pauses": dict({"inside_an_echo": len(inside),
                               "inside_max_ms": round(max([p[1] for p in inside] or [0]) * 1e3, 3),
                               "inside_generations": sorted(set(p[2] for p in inside))},
                              **{"generation_%d" % g: dict(stats([p[1] for p in pauses if p[2] == g]),
                                                           count=sum(1 for p in pauses if p[2] == g))
                                 for g in (0, 1, 2)}),
            "slowest": [{"%s->%s" % (b, a): round((row[a] - row[b]) * 1e3, 3) for b, a in zip(NAMES, NAMES[1:])}
                        for row in slowest],
            "threads": threading.active_count(), "gc_tracked_objects": len(gc.get_objects()),
            "gc_frozen_objects": gc.get_freeze_count()}


def dump():
    """Write :func:`summary` to FILE (at shutdown)."""
    if ON:
        with open(FILE, "w") as out:
            json.dump(summary(list(samples), list(gc_pauses)), out, indent=1)


if ON:
    gc.callbacks.append(_on_gc)
