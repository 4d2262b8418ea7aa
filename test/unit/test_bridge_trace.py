"""bridge/trace: the per-stage summary of traced echoes (the hooks are off unless the environment asks)."""
import gc
import json

from inspection_robot.bridge import trace


def test_tracing_is_off_by_default():
    off = trace.from_environment({})
    assert isinstance(off, trace.NoTrace) and off.on is False and off.topic is None
    off.start()
    off.stop()
    off.mark("read")   # the null tracer takes the hooks' calls and keeps nothing
    off.dump()


def test_the_environment_names_the_topic_and_the_file(tmp_path):
    tracer = trace.from_environment({"INSPECTION_BRIDGE_TRACE": "/bench/echo"})
    assert tracer.on and tracer.topic == "/bench/echo" and tracer.file == "/tmp/bridge_trace.json"
    where = str(tmp_path / "trace.json")
    tracer = trace.from_environment({"INSPECTION_BRIDGE_TRACE": "/bench/echo", "INSPECTION_BRIDGE_TRACE_FILE": where})
    assert tracer.file == where
    assert trace.from_environment({"INSPECTION_BRIDGE_TRACE": ""}).on is False


def test_a_traced_echo_is_kept_once_every_stage_was_stamped_in_order(tmp_path):
    tracer = trace.EchoTrace("/bench/echo", str(tmp_path / "trace.json"))
    tracer.mark("decoded")              # no echo in flight: ignored
    for name in trace.NAMES:
        tracer.mark(name)
    tracer.mark("read")                 # an echo that never completes is not a sample
    tracer.mark("decoded")
    assert len(tracer.samples) == 1 and list(tracer.samples[0]) == list(trace.NAMES)
    tracer.start()
    try:
        gc.collect()
    finally:
        tracer.stop()
    assert tracer.gc_pauses and tracer.gc_pauses[-1][2] == 2
    tracer.dump()
    with open(tracer.file) as written:
        assert json.load(written)["n"] == 1


def test_summary_splits_each_echo_into_its_stages_and_finds_the_gc_pause_inside_one():
    def echo(start, steps):
        row = {"read": start}
        for name, step in zip(trace.NAMES[1:], steps):
            start += step
            row[name] = start
        return row
    steps = [0.00001, 0.00002, 0.004, 0.00001, 0.00003, 0.00005]  # the rospy hand-off is the slow step
    row = echo(10.0, steps)
    fast = echo(11.0, [0.00001, 0.00002, 0.00003, 0.00001, 0.00003, 0.00005])
    result = trace.summary([row, fast], [(10.001, 0.003, 2), (20.0, 0.0001, 0)])
    assert result["n"] == 2
    assert result["steps"]["published->callback"]["max_ms"] == 4.0
    assert result["total"]["max_ms"] == round(sum(steps) * 1e3, 3)
    assert result["slowest"][-1]["published->callback"] == 4.0
    assert result["gc_pauses"]["inside_an_echo"] == 1
    assert result["gc_pauses"]["generation_2"]["count"] == 1
    assert result["gc_pauses"]["generation_0"]["max_ms"] == 0.1
