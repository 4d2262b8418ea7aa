"""Opt-in stage timings of the echo path through the bridge (a diagnostic for its tail latency).

The node makes its tracer once in main() (:func:`from_environment`) and hands it to the server and
the backend; without one they get a :class:`NoTrace`. Tracing is asked for in the bridge's
environment: ``INSPECTION_BRIDGE_TRACE=/bench/echo`` names the topic (and
``INSPECTION_BRIDGE_TRACE_FILE``, default /tmp/bridge_trace.json, written at shutdown). Off, each
hook is one attribute test (``if tracer.on``). On, one echo at a time is followed (the bench's raw
round trip has one in flight) with time.perf_counter, through the stages :data:`STAGES` name, and
every garbage collection's pause is recorded (gc.callbacks), so a slow sample can be told apart as
GC, a thread hand-off (GIL or scheduler) or work.
"""
import gc
import json
import threading
import time

TOPIC_VARIABLE = "INSPECTION_BRIDGE_TRACE"
FILE_VARIABLE = "INSPECTION_BRIDGE_TRACE_FILE"
DEFAULT_FILE = "/tmp/bridge_trace.json"

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


class NoTrace(object):
    """Tracing off: the hooks test ``on`` and go no further."""

    def __init__(self):
        self.on = False
        self.topic = None
        self.file = None

    def mark(self, stage):
        pass

    def start(self):
        pass

    def stop(self):
        pass

    def dump(self):
        pass


class EchoTrace(object):
    """Follows the echoes of ``topic`` through the stages; :meth:`dump` writes :func:`summary` to ``file``."""

    def __init__(self, topic, file=DEFAULT_FILE):
        self.on = True
        self.topic = topic
        self.file = file
        self._lock = threading.Lock()
        self._current = {}
        self.samples = []      # dicts stage -> perf_counter time, complete echoes only
        self.gc_pauses = []    # (start, seconds, generation)
        self._gc_start = 0.0

    def start(self):
        """Record every garbage collection's pause from now on (the node: until it exits)."""
        gc.callbacks.append(self._on_gc)

    def stop(self):
        """Stop recording garbage collections."""
        if self._on_gc in gc.callbacks:
            gc.callbacks.remove(self._on_gc)

    def mark(self, stage):
        """Stamp ``stage`` of the echo in flight; "read" starts a new one, "written" completes it."""
        now = time.perf_counter()
        with self._lock:
            if stage == "read":
                self._current.clear()
            elif "read" not in self._current or stage in self._current:
                return
            self._current[stage] = now
            if stage == "written" and len(self._current) == len(NAMES):
                self.samples.append(dict(self._current))
                self._current.clear()

    def _on_gc(self, phase, info):
        if phase == "start":
            self._gc_start = time.perf_counter()
        else:
            self.gc_pauses.append((self._gc_start, time.perf_counter() - self._gc_start, info.get("generation")))

    def dump(self):
        """Write :func:`summary` to ``file`` (at shutdown)."""
        with open(self.file, "w") as out:
            json.dump(summary(list(self.samples), list(self.gc_pauses)), out, indent=1)


def from_environment(environ):
    """An :class:`EchoTrace` when ``environ`` (the node's os.environ) names a topic, else a :class:`NoTrace`."""
    topic = environ.get(TOPIC_VARIABLE) or None
    if topic is None:
        return NoTrace()
    return EchoTrace(topic, environ.get(FILE_VARIABLE) or DEFAULT_FILE)


def summary(rows, pauses):
    """Per stage p50 / p99 / max (ms) of the steps between consecutive stages, and the total; the
    GC pauses that fell inside an echo; the slowest echoes' steps."""

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
