"""bridge/trace: the per-stage summary of traced echoes (the hooks are off unless the environment asks)."""
from inspection_robot.bridge import trace


def test_tracing_is_off_by_default():
    assert trace.ON is False and trace.TOPIC is None


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
