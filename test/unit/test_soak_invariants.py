"""soak_invariants: the chaos soak's invariant checkers, fed with hand-made observation sequences."""
from inspection_robot_testing.soak_invariants import (Availability, ControlKept, FaultReasons, Ledger, MemoryGrowth,
                                                      MotionAuthority, NodeLiveness, held, table)

CYCLE = 0.02


def test_motion_before_authorisation_is_a_violation():
    m = MotionAuthority()
    m.command(1.0, 0.0, 0.0)
    assert m.violations == []
    m.command(1.02, 0.3, 0.0)
    assert len(m.violations) == 1 and "without an authorised source (after start-up" in m.violations[0]


def test_authorised_motion_and_a_stop_within_one_cycle_hold():
    m = MotionAuthority()
    m.authorise(1.0)
    m.command(1.02, 0.3, 0.0)
    m.stop_cause(2.0, 2.0 + CYCLE, "hard_estop")
    m.command(2.005, 0.3, 0.0)          # already on its way before the stop took effect
    m.command(2.01, 0.0, 0.0)           # the stop
    m.command(2.03, 0.0, 0.0)
    m.tick(5.0)
    assert m.violations == [] and m.checks == 3 and abs(m.stop_latencies[0] - 0.01) < 1e-9


def test_a_stop_that_arrived_before_its_cause_was_declared_is_judged_by_its_stamp():
    m = MotionAuthority()
    m.authorise(1.0)
    m.command(1.5, 0.3, 0.0)
    m.command(2.01, 0.0, 0.0)           # the fault service had not answered yet
    m.command(2.035, 0.0, 0.0)
    m.stop_cause(2.0, 2.0 + CYCLE, "hard e-stop")
    m.tick(5.0)
    assert m.violations == [] and abs(m.stop_latencies[0] - 0.01) < 1e-9


def test_motion_that_arrived_before_its_cause_was_declared_is_still_a_violation():
    m = MotionAuthority()
    m.authorise(1.0)
    m.command(2.05, 0.3, 0.0)
    m.command(2.07, 0.0, 0.0)
    m.stop_cause(2.0, 2.0 + CYCLE, "hard e-stop")
    assert len(m.violations) == 2 and "without an authorised source (after hard e-stop)" in m.violations[0]


def test_late_stop_and_motion_after_the_deadline_are_violations():
    m = MotionAuthority()
    m.authorise(0.0)
    m.stop_cause(2.0, 2.0 + CYCLE, "heartbeat lost")
    m.command(2.05, 0.3, 0.0)
    m.command(2.07, 0.0, 0.0)
    assert len(m.violations) == 2
    assert "without an authorised source (after heartbeat lost)" in m.violations[0]
    assert "stop after heartbeat lost reached the driver 0.070 s after the cause" in m.violations[1]


def test_stop_never_seen_is_a_violation():
    m = MotionAuthority()
    m.authorise(0.0)
    m.stop_cause(2.0, 2.02, "e-stop")
    m.tick(2.5)
    assert m.violations == []
    m.tick(3.1)
    assert m.violations == ["no stop at the driver after e-stop"]


def test_node_respawned_in_time_holds_and_a_long_outage_does_not():
    n = NodeLiveness(max_down=5.0)
    n.seen(0.0, "/cloud_terrace", 10)
    n.missing(1.0, "/cloud_terrace")
    n.seen(3.0, "/cloud_terrace", 11)
    assert n.violations == [] and n.respawns == 1
    n.missing(10.0, "/camera_node")
    n.missing(16.0, "/camera_node")
    n.missing(17.0, "/camera_node")
    assert n.violations == ["/camera_node down for more than 5.0 s"]


def test_respawn_measured_from_the_kill_within_the_limit():
    n = NodeLiveness(max_down=5.0)
    n.respawned("/read_scale", 2.4)
    assert n.violations == [] and n.checks == 1
    n.respawned("/read_scale", 15.2)
    n.respawned("/camera_node", None)
    assert n.violations == ["/read_scale respawned 15.2 s after its kill (limit 5.0 s)",
                            "/camera_node respawned never after its kill (limit 5.0 s)"]


def test_fault_reasons_success_or_a_vague_reason_during_a_fault_are_violations():
    f = FaultReasons()
    f.answered("capture", "failed", "camera http://x refused the credentials (HTTP 401, digest)", ["HTTP 401"])
    assert f.violations == [] and f.checks == 1
    f.answered("capture", "success", "", ["HTTP 401"])
    f.answered("capture", "failed", "internal error", ["unreachable", "timed out"])
    assert f.violations == ["capture succeeded during the fault",
                            "capture failed without naming the fault (unreachable | timed out): 'internal error'"]


def test_memory_growth_against_the_level_after_warm_up():
    g = MemoryGrowth(warmup=10.0, window=3)
    for t in range(0, 40):
        g.sample(float(t), "/a", 1, 100e6)
        g.sample(float(t), "/b", 2, 100e6 if t < 20 else 120e6)
    g.sample(0.0, "/c", 3, 50e6)        # too short to judge (respawned and killed again)
    g.finish()
    assert g.checks == 2
    assert g.violations == ["/b (pid 2) grew from 100.0 to 120.0 MB (+20 %)"]


def test_ledger_lost_and_corrupted():
    ledger = Ledger()
    ledger.stored("virtual obstacle", "w1", [[0, 0], [1, 1]])
    ledger.stored("virtual obstacle", "w2", [[2, 2], [3, 3]])
    ledger.stored("virtual obstacle", "w3", [[4, 4], [5, 5]])
    ledger.removed("virtual obstacle", "w3")
    ledger.listed("virtual obstacle", {"w1": [[0, 0], [1, 1]], "w2": [[2, 2], [3, 4]]})
    assert ledger.checks == 2
    assert ledger.violations == ["virtual obstacle w2 corrupted: [[2, 2], [3, 4]], stored [[2, 2], [3, 3]]"]
    ledger.listed("virtual obstacle", {})
    assert "virtual obstacle w1 lost" in ledger.violations


def test_table_names_faults_and_results():
    a, b = Availability(10.0), Availability(10.0)
    a.recovered("head", 1.5)
    text = table({"head unplugged and back": 3}, [a, b])
    assert "head unplugged and back" in text and "     3" in text
    assert "HELD" in text and "NOT EXERCISED" in text
    assert not held([a, b]) and held([a])
    b.recovered("camera", None)
    assert "VIOLATED" in table({}, [b])


def test_calls_across_a_restart_fail_only_during_the_absence_and_say_so():
    from inspection_robot_testing.soak_invariants import CallsAcrossRestart
    away = "service /file_control is not available: its node is restarting or down (x)"
    checker = CallsAcrossRestart()
    checker.calls("/file_control", 10.0, 12.0, [(9.0, 9.1, True, ""), (9.9, 10.2, False, away),
                                                (11.0, 11.1, False, away), (12.1, 12.2, True, "")])
    assert checker.checks == 5 and checker.violations == []
    checker.calls("/file_control", 10.0, 12.0, [(11.0, 11.1, False, "transport error completing service call"),
                                                (12.1, 12.2, False, away)])
    assert len(checker.violations) == 2
    assert "without saying so" in checker.violations[0] and "while its node was there" in checker.violations[1]
    checker.calls("/file_control", 10.0, 12.0, [(11.0, 11.1, False, away)])
    assert checker.violations[-1] == "no call of /file_control after its node came back"


def test_control_kept_counts_each_reconnect_and_names_a_loss():
    kept = ControlKept()
    assert not held([kept])                       # not exercised: not held
    kept.observed("reconnect", True)
    assert held([kept])
    kept.observed("reconnect", False, "mode 0, offline True")
    assert not held([kept]) and kept.checks == 2
    assert kept.violations == ["reconnect: control lost after the grant (mode 0, offline True)"]


def test_spoofs_refused_names_what_took_effect():
    from inspection_robot_testing.soak_invariants import SpoofsRefused
    spoofs = SpoofsRefused()
    assert not held([spoofs])
    spoofs.observed("spoof", True)
    assert held([spoofs])
    spoofs.observed("spoof", False, "2 robot_status without the obstacle bit, mode 1")
    assert spoofs.violations == ["spoof: a spoofed input took effect (2 robot_status without the obstacle bit, mode 1)"]
