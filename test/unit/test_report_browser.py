"""The patrol report in a real browser (Debian's chromium, headless, driven by Playwright; no roscore):
a report of the simulated yard's patrol (its six stops and eight presets on config/maps/substation,
filled by the patrol state machine with every kind of reading: alarms, checks, failures, uncertain
values with the reader's long reasons, trends, lamps, switches, thermal, foreign objects, 1920x1080
pictures) must fit a 1280-px window without horizontal scrolling and an A4 page's width when printed,
show every picture through its relative link, and print to a sane number of A4 pages. The screenshot
and the PDF go to test_logs/screens/. Skipped only when chromium or Playwright is absent."""
import glob
import json
import math
import os
import re

import numpy as np
import pytest

from inspection_robot.i18n import CATALOGUE_FILE, load_catalogue, translator
from inspection_robot.lazy import lazy_import
from inspection_robot.nav.gridmap import load_map
from inspection_robot.task.patrol import STEP_INSPECT, Inspection, Patrol, PatrolConfig
from inspection_robot.task.report import write_reports
from inspection_robot.task.spec import ResolvedPreset, parse_task
from inspection_robot.task.store import ResultStore
from inspection_robot.task.track import PathThinner
from inspection_robot_testing.yard_patrol import YARD_STOPS

cv2 = lazy_import("cv2")
CHROMIUM = "/usr/bin/chromium"
HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.dirname(os.path.dirname(HERE))
SCREENS = os.path.join(PACKAGE, "test_logs", "screens")
MAP = os.path.join(PACKAGE, "config", "maps", "substation.yaml")
WINDOW_PX = 1280
A4_CONTENT_PX = int((210 - 2 * 12) / 25.4 * 96)   # @page A4 with 12 mm margins, at CSS's 96 px per inch
DAY_S = 86400.0
CATALOGUE = load_catalogue(os.path.join(PACKAGE, CATALOGUE_FILE))

if not os.access(CHROMIUM, os.X_OK):
    pytest.skip("no %s" % CHROMIUM, allow_module_level=True)
try:
    import pypdfium2 as pdfium
    from playwright import sync_api
except ImportError:   # the Python 3.8 (Noetic) unit-test environment has neither
    pytest.skip("Playwright or pypdfium2 is not installed in this Python", allow_module_level=True)

# per preset id: its targets (name, kind, unit, decimals)
TARGETS = {
    "transformer_1_left": [("transformer_1_left/oil_temp", "pointer", "C", 0),
                           ("transformer_1_left/oil_level", "pointer", "", 1)],
    "transformer_1": [("transformer_1/pressure", "pointer", "MPa", 2)],
    "cabinet_1": [("cabinet_1/ammeter", "pointer", "A", 0), ("cabinet_1/lamp_run", "lamp", "", 0),
                  ("cabinet_1/switch", "switch", "", 0)],
    "cabinet_2": [("cabinet_2/voltmeter", "pointer", "kV", 1)],
    "cabinet_2_zoom": [("cabinet_2/sf6", "pointer", "MPa", 3)],
    "breaker_1": [("breaker_1/counter_pressure_gauge_with_a_long_name_nobody_shortened", "pointer", "MPa", 2)],
    "breaker_1_thermal": [("breaker_1/contact_hot_spot", "thermal", "C", 1)],
    "transformer_1_thermal": ([("transformer_1/bushing_%s" % p, "thermal", "C", 1) for p in "abc"]
                              + [("transformer_1/ambient_plate", "thermal", "C", 1)]),
    "breaker_2": [("breaker_2/sf6", "pointer", "MPa", 2)],
}
# per target name: (value, confidence, the reader's doubt or "")
VALUES = {
    "transformer_1_left/oil_temp": (93.4471, 92.0, ""),          # alarm (band 0..85)
    "transformer_1_left/oil_level": (0.55512, 88.0, ""),
    "transformer_1/pressure": (0.80273, 35.0, "uncertain: box 0: needle_confidence 35 < 50 and the dial's marks "
                                              "were found on only 5 of 16 expected positions (glare from the "
                                              "low sun on the glass covers the upper half of the scale)"),
    "cabinet_1/ammeter": (412.2, 90.0, ""),
    "cabinet_1/lamp_run": (2.0, 95.0, ""),
    "cabinet_1/switch": (0.0, 97.0, ""),                          # alarm: must be closed
    "cabinet_2/voltmeter": (10.4823, 91.0, ""),
    "cabinet_2/sf6": (0.61744, 40.0, "uncertain: box 0: pointer_width 2.1 px below 3 px"),   # check (band)
    "breaker_1/counter_pressure_gauge_with_a_long_name_nobody_shortened": (0.6012, 89.0, ""),   # trend
    "breaker_1/contact_hot_spot": (55.1963, 99.0, ""),
    "transformer_1/bushing_a": (58.61, 98.0, ""),   # inside its band, a serious defect by dt (84 %)
    "transformer_1/bushing_b": (31.02, 98.0, ""),
    "transformer_1/bushing_c": (30.44, 98.0, ""),
    "transformer_1/ambient_plate": (24.91, 99.0, ""),
}
# thermal diagnosis keys of the calibration (task.checks._target_entry)
PHASES = dict([("transformer_1/bushing_%s" % p, {"phase": p.upper(), "device": "transformer_1",
                                                 "equipment_class": "connector"}) for p in "abc"]
              + [("transformer_1/ambient_plate", {"phase": "ambient"})])
BANDS = {"transformer_1_left/oil_temp": [0.0, 85.0], "transformer_1/pressure": [0.4, 1.2],
         "cabinet_1/ammeter": [0.0, 500.0], "cabinet_1/switch": [1.0, 1.0], "cabinet_2/sf6": [0.65, 0.9],
         "breaker_1/counter_pressure_gauge_with_a_long_name_nobody_shortened": [0.4, 0.62],
         "breaker_1/contact_hot_spot": [-50.0, 60.0], "breaker_2/sf6": [0.5, 0.7],
         "transformer_1/bushing_a": [-50.0, 60.0]}


def picture(path, label):
    """An annotated picture as read_scale writes one: 1920x1080 JPEG."""
    image = np.full((1080, 1920, 3), 90, np.uint8)
    cv2.circle(image, (960, 540), 400, (230, 230, 230), -1)
    cv2.line(image, (960, 540), (1200, 300), (0, 0, 200), 12)
    cv2.putText(image, label[:40], (40, 100), cv2.FONT_HERSHEY_SIMPLEX, 2.0, (0, 255, 0), 4)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    assert cv2.imwrite(path, image)


def patrol_store(root):
    """A results store holding the yard patrol ``yard`` (every stop, breaker_2 unreachable), its
    driven path and a week of history for the trend; returns (store, task id)."""
    os.makedirs(os.path.join(root, "tasks"))
    store = ResultStore(os.path.join(root, "tasks", "results.sqlite"))
    clock = [1.79e9]

    def resolve(name):
        preset_id = name.split("/")[-1]
        targets = [dict(PHASES.get(n, {}), name=n, kind=k, unit=u, decimals=d) for n, k, u, d in TARGETS[preset_id]]
        return ResolvedPreset(os.path.join(root, "presets", preset_id, "20261127_080000"), targets, {})

    # the trending gauge's last week (oldest first), read by earlier patrols
    trending = "breaker_1/counter_pressure_gauge_with_a_long_name_nobody_shortened"
    for day, value in enumerate([0.45, 0.48, 0.52, 0.55, 0.58]):
        store.add_readings([{"task_id": "week_%d" % day, "stop": 0, "stop_name": "breaker_1", "preset_index": 0,
                             "preset": "/p", "target": 0, "target_name": trending, "kind": "pointer", "status": "read",
                             "value": value, "unit": "MPa", "alarm": "normal", "low": 0.4, "high": 0.62,
                             "confidence": 90.0, "picture": "", "x": 0.0, "y": 0.0, "yaw": 0.0,
                             "time": clock[0] - (5 - day) * DAY_S, "reason": "", "source_picture": "", "roi": ""}])
    stops = [{"name": name, "pose": {"x": pose[0], "y": pose[1], "yaw": pose[2]},
              "presets": [{"preset": "presets/" + p[0],
                           "alarms": dict((n, BANDS[n]) for n, _k, _u, _d in TARGETS[p[0]] if n in BANDS),
                           "foreign": p[0] == "cabinet_2"} for p in presets]}
             for name, pose, presets in YARD_STOPS]
    task = parse_task(json.dumps({"id": "yard_20261127_0800", "stops": stops, "retries": 0}), resolve,
                      lambda x, y: None, 0)
    task.planned_length_m = 61.8
    patrol = Patrol(store, PatrolConfig(1.0, (2.0, 2.0, 0.0), 20.0, 10.0, 0), clock[0])
    patrol.set_mode(0)
    patrol.submit(task, clock[0])
    track = PathThinner(task.task_id)
    here = (2.0, 2.0)
    while True:
        step = patrol.next_step(clock[0])
        if step is None:
            break
        started = clock[0]
        if step.kind == STEP_INSPECT:
            names = [t["name"] for t in step.preset["targets"]]
            pictures = [os.path.join(root, "pictures", step.preset["preset"].split("/")[-1],
                                     "20261127_08%02d%02d_read_%02d.jpg" % (step.stop, step.preset_index, k))
                        for k in range(len(names))]
            for path, name in zip(pictures, names):   # an annotated copy of the frame per target, as read_scale writes
                picture(path, name)
            # what read_scale read: the capture (a thermal target: the raw temperature frame), each box in it
            capture = os.path.join(root, "captures", "%s_20261127_08%02d%02d.jpg" % (
                step.preset["preset"].split("/")[-1], step.stop, step.preset_index))
            picture(capture, "capture")
            sources = [{"picture": capture if t["kind"] != "thermal" else capture[:-4] + "_thermal.tiff",
                        "roi": [100 + 300 * k, 200, 350 + 300 * k, 200, 350 + 300 * k, 500, 100 + 300 * k, 500]}
                       for k, t in enumerate(step.preset["targets"])]
            values = [VALUES.get(n, (0.6, 90.0, ""))[0] for n in names]
            foreign = (1, 80.0, pictures[0]) if step.preset.get("foreign") else None
            inspection = Inspection(values, [VALUES.get(n, (0, 90.0, ""))[1] for n in names], pictures,
                                    (step.x, step.y, step.yaw), foreign, [VALUES.get(n, (0, 0, ""))[2] for n in names],
                                    sources)
            clock[0] += 12.0
            outcome, detail = "ok", inspection
        elif step.stop == len(YARD_STOPS) - 1:
            clock[0] += 30.0
            outcome, detail = "failed", "no path to the goal: the planner found none (blocked by a parked truck)"
        else:   # drive there in a straight line at 0.8 m/s, robot_status at 10 Hz
            steps = int(math.hypot(step.x - here[0], step.y - here[1]) / 0.08) + 1
            for i in range(1, steps + 1):
                clock[0] += 0.1
                track.add(clock[0], here[0] + (step.x - here[0]) * i / steps, here[1] + (step.y - here[1]) * i / steps,
                          step.yaw)
            here = (step.x, step.y)
            outcome, detail = "ok", ""
        patrol.step_done(step, outcome, detail, started, clock[0])
    store.add_poses(task.task_id, track.take(final=True))
    return store, task.task_id


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = str(tmp_path_factory.mktemp("data_root"))
    store, task_id = patrol_store(root)
    readings = store.readings(task_id=task_id)
    paths = write_reports(os.path.join(root, "tasks", "reports", task_id), store.task(task_id), readings,
                          store.steps(task_id), root, "v-test", store.meter_histories(readings, 20),
                          store.driven_path(task_id), load_map(MAP))
    # the same patrol's report in Chinese, beside it (pictures at the same relative place)
    chinese = write_reports(os.path.join(root, "tasks", "reports", task_id + "_zh"), store.task(task_id), readings,
                            store.steps(task_id), root, "v-test", store.meter_histories(readings, 20),
                            store.driven_path(task_id), load_map(MAP), translator("zh-CN", CATALOGUE), "zh-CN")
    return paths, json.load(open(paths["report.json"])), chinese


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu"])
        yield browser
        browser.close()


def overflow(page):
    """(the document's scroll width, its client width, the widest element sticking out, or None)."""
    return page.evaluate("""() => {
        const doc = document.documentElement, width = doc.clientWidth;
        let worst = null;
        for (const el of document.querySelectorAll('body *')) {
            const r = el.getBoundingClientRect();
            if (r.right > width + 0.5 && (!worst || r.right > worst[1]))
                worst = [el.tagName + '.' + (el.getAttribute('class') || ''), r.right];
        }
        return [doc.scrollWidth, width, worst];
    }""")


def test_the_report_fits_a_1280_px_window_with_every_picture_shown(report, browser):
    paths, data, _chinese = report
    counts = data["summary"]["counts"]
    assert (counts["alarms"], counts["checks"], counts["failed"], counts["needs_review"], counts["trends"]) == \
        (4, 1, 1, 2, 1)   # the fixture holds every kind of attention (alarms: oil, switch, foreign, bushing A)
    assert data["summary"]["thermal_defects"] == {"general": 0, "serious": 1, "critical": 0}
    assert data["summary"]["distance_driven_m"] > 40.0
    page = browser.new_page(viewport={"width": WINDOW_PX, "height": 900})
    page.goto("file://" + paths["report.html"], wait_until="load")
    os.makedirs(SCREENS, exist_ok=True)
    page.screenshot(path=os.path.join(SCREENS, "report_1280.png"), full_page=True)
    scroll, client, worst = overflow(page)
    assert scroll <= WINDOW_PX and worst is None, (scroll, client, worst)
    images = page.evaluate("() => Array.from(document.images).map(i => [i.getAttribute('src'), i.naturalWidth])")
    assert all(width == 1920 for _src, width in images), images
    # one picture per camera view of a preset with every box on it: a visible view per preset (its
    # capture, boxes numbered in their states' colours), the thermal presets' annotated frames once each
    views = page.evaluate("""() => Array.from(document.querySelectorAll('.preset')).map(p => [
        p.querySelectorAll('.pics svg.view').length, p.querySelectorAll('.pics svg.view polygon').length,
        p.querySelectorAll('.pics img').length, p.querySelectorAll('.values tr').length - 1])""")
    # [views, boxes, pictures, rows] per preset: cabinet_2 also shows its foreign-object picture, the
    # unreachable breaker_2 has none
    assert views == [[1, 2, 0, 2], [1, 1, 0, 1], [1, 4, 0, 4], [1, 3, 0, 3], [1, 1, 1, 2], [1, 1, 0, 1], [1, 1, 0, 1],
                     [1, 1, 0, 1], [0, 0, 0, 1]], views
    sizes = page.evaluate("() => Array.from(document.querySelectorAll('svg.view')).map(s => s.getAttribute('viewBox'))")
    assert set(sizes) == {"0 0 1920 1080"} and len(sizes) == 8, sizes
    loaded = page.evaluate("""() => Promise.all(Array.from(document.querySelectorAll('svg.view image')).map(i =>
        new Promise(done => { const probe = new Image(); probe.onload = () => done(probe.naturalWidth);
                              probe.onerror = () => done(0); probe.src = i.href.baseVal; })))""")
    assert loaded and all(width == 1920 for width in loaded), loaded
    # each stop's heading inside its first preset's block (a page break cannot leave it alone), and
    # target names break only after their separators
    assert page.locator(".preset > h3").count() == len(YARD_STOPS) and page.locator("article.stop > h3").count() == 0
    assert page.evaluate("() => document.querySelector('.values td').innerHTML").count("<wbr>") >= 1
    assert page.locator("svg.yard g.stop").count() == len(YARD_STOPS)
    assert page.locator("svg.yard g.stop.alarm").count() == 4 and page.locator("svg.yard g.stop.failed").count() == 1
    text = page.inner_text("body")
    assert "0.80 MPa" in text and "0.80273" not in text and "93 °C" in text and "lit green" in text
    assert "serious thermal defects" in text and "serious defect (connector): dt 84 % >= 80 %" in text
    assert text.index("Summary") < text.index("Needs attention (8)") < text.index("Yard map") < text.index("Stops")
    page.close()


def print_pages(page, pdf_path, prefix):
    """The page printed to an A4 PDF at ``pdf_path``, every page rendered to SCREENS/<prefix><n>.png to look
    at (pdfium renders BGR); returns the PDF's bytes and its page count."""
    pdf = page.pdf(path=pdf_path, format="A4", print_background=True, prefer_css_page_size=True)
    document = pdfium.PdfDocument(pdf)
    for stale in glob.glob(os.path.join(SCREENS, prefix + "*.png")):   # an earlier, longer report's
        os.unlink(stale)
    for n in range(len(document)):
        picture = document[n].render(scale=1.0).to_numpy()
        assert cv2.imwrite(os.path.join(SCREENS, "%s%d.png" % (prefix, n + 1)), picture)
    return pdf, len(document)


def test_the_report_in_chinese_fits_and_prints_like_the_english_one(report, browser):
    paths, _data, chinese = report
    page = browser.new_page(viewport={"width": WINDOW_PX, "height": 900})
    page.goto("file://" + chinese["report.html"], wait_until="load")
    page.screenshot(path=os.path.join(SCREENS, "report_zh_1280.png"), full_page=True)
    scroll, client, worst = overflow(page)
    assert scroll <= WINDOW_PX and worst is None, (scroll, client, worst)
    text = page.inner_text("body")
    assert page.evaluate("document.documentElement.lang") == "zh-CN"
    for words in ("巡检报告 yard_20261127_0800", "摘要", "需要关注（8）", "场地地图", "停靠点", "告警", "亮绿灯", "93 °C",
                  "严重红外缺陷", "0.4 .. 1.2 MPa"):
        assert words in text, words
    for english in ("Summary", "Needs attention", "Yard map", "no limits", "needs review", "lit green", "readings",
                    "check", "objects"):
        assert english not in text, english
    assert page.locator("svg.view").count() == 8 and page.locator(".preset > h3").count() == len(YARD_STOPS)
    page.emulate_media(media="print")
    page.set_viewport_size({"width": A4_CONTENT_PX, "height": 1000})
    scroll, client, worst = overflow(page)
    assert scroll <= A4_CONTENT_PX and worst is None, (scroll, client, worst)
    _pdf, pages = print_pages(page, os.path.join(SCREENS, "report_zh_a4.pdf"), "report_zh_a4_page_")
    assert 2 <= pages <= 12, pages
    page.close()


def test_the_report_prints_on_a4_without_cutting_anything(report, browser):
    paths, _data, _chinese = report
    page = browser.new_page(viewport={"width": A4_CONTENT_PX, "height": 1000})
    page.emulate_media(media="print")
    page.goto("file://" + paths["report.html"], wait_until="load")
    scroll, client, worst = overflow(page)   # what the printed page's width must hold
    page.screenshot(path=os.path.join(SCREENS, "report_print_a4_width.png"), full_page=True)
    assert scroll <= A4_CONTENT_PX and worst is None, (scroll, client, worst)
    pdf_path = os.path.join(SCREENS, "report_a4.pdf")
    pdf, rendered = print_pages(page, pdf_path, "report_a4_page_")   # every page a picture to look at
    pages = len(re.findall(rb"/Type\s*/Page\b(?!s)", pdf))
    assert rendered == pages
    assert len(pdf) > 20000 and os.path.getsize(pdf_path) == len(pdf)
    assert 2 <= pages <= 12, pages   # summary + attention + map + nine presets, not one page per picture
    boxes = re.findall(rb"/MediaBox\s*\[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", pdf)
    assert boxes and all(abs(float(w) - 595.9) < 2 and abs(float(h) - 842.9) < 2 for w, h in boxes), boxes[:3]
    page.close()
