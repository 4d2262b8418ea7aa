#!/usr/bin/env python3
"""Benchmark of the operator console in headless chromium against the whole simulated robot.

Starts its own master and sim.launch (free ports), opens /console/ and prints one JSON line per
figure: first contentful paint and time to the first decoded status; the status refresh rate the
page really renders against robot_status's own rate; key-up -> zero velocity at the (simulated)
driver over repeated presses; and the page's JS heap and DOM size over a long run (default 10
minutes, BENCH_CONSOLE_MINUTES to change) — "growth" compares the end with the level after a
one-minute warm-up.
"""
import os
import subprocess
import sys
import time

from benchlib import free_port, percentile, report  # noqa: E402

MINUTES = float(os.environ.get("BENCH_CONSOLE_MINUTES", "10"))
PRESSES = 20
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--enable-precise-memory-info",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def wait(condition, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.01)
    raise RuntimeError("timed out waiting for " + what)


def main():
    master_port, ws_port = free_port(), free_port()
    os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % master_port
    launch = subprocess.Popen(["roslaunch", "-p", str(master_port), "inspection_robot", "sim.launch",
                               "port:=%d" % ws_port], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        run(ws_port)
    finally:
        launch.terminate()
        launch.wait(30)


def run(ws_port):
    import rospy
    from geometry_msgs.msg import TwistStamped
    from playwright.sync_api import sync_playwright
    from inspection_robot.msg import RobotStatus

    wait(lambda: subprocess.call(["rostopic", "list"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) == 0,
         60, "the master")
    rospy.init_node("bench_console", anonymous=True, disable_signals=True)
    chassis = []
    statuses = []
    rospy.Subscriber("/sim/chassis_cmd", TwistStamped, lambda m: chassis.append(m), queue_size=1000)
    rospy.Subscriber("/robot_status", RobotStatus, lambda m: statuses.append(time.monotonic()), queue_size=100)
    wait(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 120, "the bridge")
    url = "http://127.0.0.1:%d/console/" % ws_port
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1200})
        errors = []
        page.on("pageerror", lambda err: errors.append(str(err)))
        started = time.monotonic()
        page.goto(url)
        page.wait_for_function("document.querySelector('#status tbody').rows.length > 5", timeout=60000)
        first_status_ms = (time.monotonic() - started) * 1000.0
        paint = page.evaluate("performance.getEntriesByType('paint').map(e => [e.name, e.startTime])")
        fcp = dict(paint).get("first-contentful-paint")
        report(bench="console", figure="first contentful paint", ms=round(fcp, 1), target_ms=1000)
        report(bench="console", figure="page load to first decoded robot_status", ms=round(first_status_ms, 1))

        # Refresh: statuses rendered by the page vs statuses published, over 10 s.
        count = "window.consoleStats.status"
        page_before, ros_before = page.evaluate(count), len(statuses)
        time.sleep(10.0)
        page_rate = (page.evaluate(count) - page_before) / 10.0
        ros_rate = (len(statuses) - ros_before) / 10.0
        report(bench="console", figure="status refresh", page_hz=round(page_rate, 2),
               robot_status_hz=round(ros_rate, 2))

        # Key-up -> zero velocity at the driver.
        page.click("#acquire")
        wait(lambda: page.evaluate("document.getElementById('mode').textContent").endswith("backend remote control"),
             30, "backend control")
        page.locator("body").focus()
        latencies = []
        for _ in range(PRESSES):
            page.keyboard.down("ArrowUp")
            time.sleep(0.6)
            del chassis[:]
            key_up = time.time()
            page.keyboard.up("ArrowUp")
            stop = wait(lambda: next((m for m in list(chassis) if m.twist.linear.x == 0.0
                                      and m.header.stamp.to_sec() >= key_up), None), 5, "zero velocity")
            latencies.append((stop.header.stamp.to_sec() - key_up) * 1000.0)
            time.sleep(0.8)
        page.click("#release")
        report(bench="console", figure="key-up -> zero velocity at the driver", n=PRESSES,
               p50_ms=round(percentile(latencies, 0.5), 1), p99_ms=round(percentile(latencies, 0.99), 1),
               control_cycle_ms=20.0)

        # Memory over a long run with status, pictures and the map refreshing.
        def sample():
            return page.evaluate("[performance.memory.usedJSHeapSize, document.getElementsByTagName('*').length]")
        samples = []
        end = time.monotonic() + MINUTES * 60.0
        while time.monotonic() < end:
            page.evaluate("window.gc ? window.gc() : null")
            samples.append((time.monotonic() - started, ) + tuple(sample()))
            time.sleep(min(30.0, max(end - time.monotonic(), 0.0)) or 0.01)
        samples.append((time.monotonic() - started, ) + tuple(sample()))
        warm = [s for s in samples if s[0] >= 60.0] or samples
        base_heap, base_nodes = min(s[1] for s in warm[:3]), warm[0][2]
        last_heap, last_nodes = samples[-1][1], samples[-1][2]
        report(bench="console", figure="browser memory over the run", minutes=MINUTES,
               heap_after_warmup_mb=round(base_heap / 1e6, 2), heap_end_mb=round(last_heap / 1e6, 2),
               heap_max_mb=round(max(s[1] for s in warm) / 1e6, 2),
               growth_percent=round(100.0 * (last_heap - base_heap) / base_heap, 1),
               dom_nodes_after_warmup=base_nodes, dom_nodes_end=last_nodes, js_errors=len(errors))
        browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
