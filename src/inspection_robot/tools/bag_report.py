"""bag_report: turn a recorded run (rosbag) into a picture and a short text summary.

    bag_report BAG [BAG ...] [--out PNG] [--ns NAMESPACE] [--no-plot]
    bag_report --check BAG [BAG ...] [--ns NAMESPACE]

``--check`` only says whether the bags can be replayed (replay.launch runs it first): readable and
indexed, robot_status of one robot, and status_control's inputs (REPLAY_INPUTS) of the right types.

Reads the bags (recording/ros_bag_reading.py, rosbag Python API; several splits of one run are read in
time order), feeds recording.summary.RunAnalyzer and prints its summary (duration, distance, stops, readings,
alarms, faults). Unless ``--no-plot`` it writes a PNG (default: next to the first bag,
``<bag>.png``): the driven path over the recorded map with virtual obstacles, stops, goals,
alarms and 3-D obstacles marked, and time plots of speed, battery and mode (matplotlib, Agg).

A missing, truncated or foreign bag, or a topic of an unexpected type, ends with one line
``bag_report: error: ...`` naming the file, topic and type, exit status 1, no traceback.
Run it with ``scripts/rosenv bag_report ...`` or ``rosrun inspection_robot bag_report ...``.
"""
import argparse
import math
import os
import sys

from inspection_robot.recording.summary import READING_ALARMS, format_summary, reading_text
from inspection_robot.recording.ros_bag_reading import ReportError, check_replayable, read_run
from inspection_robot.task.states import STATUS_FAILED

MAX_LISTED = 14   # readings listed (and numbered R<i> on the map) in the picture


def grid_image(grid):
    """(grey level image, extent) of an OccupancyGrid: free near-white, occupied black, unknown grey."""
    import numpy as np
    info = grid.info
    cells = np.asarray(grid.data, dtype=np.int16).reshape(info.height, info.width)
    shade = np.where(cells < 0, 0.75, 0.97 - 0.97 * np.clip(cells, 0, 100) / 100.0)
    extent = (info.origin.position.x, info.origin.position.x + info.width * info.resolution,
              info.origin.position.y, info.origin.position.y + info.height * info.resolution)
    return shade, extent


def plot_run(summary, grid, virtual, out_path, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from inspection_robot.interface import MODE_NAMES

    fig = plt.figure(figsize=(15, 12), dpi=100)
    spec = fig.add_gridspec(4, 2, width_ratios=(1.35, 1), height_ratios=(1, 1, 1, 1.1), hspace=0.35, wspace=0.18)
    ax = fig.add_subplot(spec[:3, 0])
    xs, ys = np.asarray(summary.x, float), np.asarray(summary.y, float)
    if grid is not None:
        shade, extent = grid_image(grid)
        ax.imshow(shade, cmap="gray", vmin=0, vmax=1, origin="lower", extent=extent, interpolation="nearest")
    if virtual is not None and (grid_image(virtual)[0] <= 0.5).any():
        vshade, vextent = grid_image(virtual)
        mask = np.ma.masked_where(vshade > 0.5, np.ones_like(vshade))
        ax.imshow(mask, cmap="autumn", alpha=0.8, origin="lower", extent=vextent, interpolation="nearest")
        ax.plot([], [], color="red", lw=4, label="virtual obstacle")   # view_bounds keeps its cells in view
    ax.plot(xs, ys, color="tab:blue", lw=2, label="driven path (%.1f m)" % summary.distance, zorder=2)
    finite = np.isfinite(xs) & np.isfinite(ys)
    markers = (("goals", summary.goals, "*", "tab:green", 16), ("stops", summary.stops, "o", "orange", 10),
               ("readings", summary.readings, "D", "tab:cyan", 8),
               ("alarms", summary.alarms, "^", "red", 12), ("3-D obstacles", summary.obstacles, "x", "magenta", 11))
    for label, events, marker, color, size in markers:
        if events:
            ax.plot([e.x for e in events], [e.y for e in events], marker, color=color, ms=size, ls="none",
                    mec="black" if marker != "x" else color, label=legend_label(label, events), zorder=3)
    if finite.any():   # above the stop markers: the run starts and ends at rest, i.e. at a stop
        ax.plot(xs[finite][0], ys[finite][0], "o", color="green", ms=7, mec="white", mew=1.5, label="start",
                zorder=5)
        ax.plot(xs[finite][-1], ys[finite][-1], "s", color="black", ms=6, mec="white", mew=1.5, label="end",
                zorder=5)
    bounds = view_bounds(list(zip(xs[finite], ys[finite])) + [
        (e.x, e.y) for group in (summary.goals, summary.stops, summary.readings, summary.alarms, summary.obstacles)
        for e in group], [occupied_bounds(virtual)] if virtual is not None else [])
    if bounds is not None:
        ax.set_xlim(*bounds[0])
        ax.set_ylim(*bounds[1])
    for i, stop in enumerate(summary.stops[:30]):
        _label(ax, "S%d" % (i + 1), stop.x, stop.y, bounds, 0, fontsize=9)
    for label, x, y, alarm in _reading_labels(summary.readings[:MAX_LISTED]):   # R<i>: line i of the list below
        _label(ax, label, x, y, bounds, 1, fontsize=8, color="darkred" if alarm else "teal")
    placed = []
    for alarm in summary.alarms[:12]:   # labels at one spot are stacked (stop, reading, alarms), not overlaid
        if not (np.isfinite(alarm.x) and np.isfinite(alarm.y)):
            continue
        below = sum(1 for p in placed if abs(p[0] - alarm.x) < 0.5 and abs(p[1] - alarm.y) < 0.5)
        placed.append((alarm.x, alarm.y))
        _label(ax, "%s (%.0f s)" % (alarm.text, alarm.t), alarm.x, alarm.y, bounds, below + 2, fontsize=8,
               color="darkred")
    ax.set_xlabel("x (m, map)")
    ax.set_ylabel("y (m, map)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.85)
    ax.set_title(title, fontsize=11)

    t = np.asarray(summary.t, float)
    axes = [fig.add_subplot(spec[i, 1]) for i in range(3)]
    _lists(fig.add_subplot(spec[3, :]), summary)
    axes[0].plot(t, summary.speed, color="tab:blue")
    axes[0].set_ylabel("speed (m/s)")
    axes[1].plot(t, summary.battery, color="tab:green")
    axes[1].set_ylabel("battery (%)")
    axes[2].step(t, summary.mode, where="post", color="tab:purple")
    axes[2].set_yticks(sorted(MODE_NAMES))
    axes[2].set_yticklabels([MODE_NAMES[m] for m in sorted(MODE_NAMES)])
    axes[2].set_ylim(-0.5, max(MODE_NAMES) + 0.5)
    axes[2].set_ylabel("mode")
    axes[2].set_xlabel("time since start (s)")
    for a in axes:
        a.grid(True, alpha=0.3)
        for alarm in summary.alarms:
            a.axvline(alarm.t, color="red", alpha=0.35, lw=1)
    axes[0].set_title("speed, battery and mode (red lines: alarms)", fontsize=10)
    fig.savefig(out_path, bbox_inches="tight")
    plt.close(fig)


def _reading_labels(readings, near_m=0.5):
    """(label, x, y, any alarm) per spot: the readings taken at one spot share a label ``R2-R5``."""
    spots = []   # [x, y, [numbers], alarm]
    for i, r in enumerate(readings):
        if r.x != r.x:   # no pose yet
            continue
        spot = next((s for s in spots if abs(s[0] - r.x) < near_m and abs(s[1] - r.y) < near_m), None)
        if spot is None:
            spot = [r.x, r.y, [], False]
            spots.append(spot)
        spot[2].append(i + 1)
        spot[3] = spot[3] or r.alarm in READING_ALARMS
    return [("R%d" % n[0] if len(n) == 1 else "R%d-R%d" % (n[0], n[-1]) if n[-1] - n[0] == len(n) - 1
             else "R" + ",".join(str(k) for k in n), x, y, alarm) for x, y, n, alarm in spots]


def _clip(text, width):
    return text if len(text) <= width else text[:width - 3] + "..."


def _lists(ax, summary):
    """The readings (value, unit, alarm state) and the alarms and faults, as text under the plots."""
    ax.axis("off")
    readings = ["readings: %d (%d alarm, %d failed)" % (
        len(summary.readings), sum(1 for r in summary.readings if r.alarm in READING_ALARMS),
        sum(1 for r in summary.readings if r.status == STATUS_FAILED))]
    readings += [_clip("R%-3d %5.0f s  %s" % (i + 1, r.t, reading_text(r)), 120)
                 for i, r in enumerate(summary.readings[:MAX_LISTED])]
    events = ["alarms: %d" % len(summary.alarms)] + [_clip("%5.0f s  %s" % (e.t, e.text), 80)
                                                     for e in summary.alarms[:8]]
    events += ["faults: %d" % len(summary.faults)] + [_clip("%5.0f s  %s" % (e.t, e.text), 80)
                                                      for e in summary.faults[:6]]
    if len(summary.readings) > MAX_LISTED:
        readings.append("... and %d more (text summary)" % (len(summary.readings) - MAX_LISTED))
    ax.text(0.0, 1.0, "\n".join(readings), va="top", ha="left", family="monospace", fontsize=8,
            transform=ax.transAxes)
    ax.text(0.63, 1.0, "\n".join(events), va="top", ha="left", family="monospace", fontsize=8, color="darkred",
            transform=ax.transAxes)


def legend_label(name, events):
    """``alarms (3)``, or ``alarms (3; 1 at an unknown position)`` when some cannot be drawn."""
    unknown = sum(1 for e in events if not (math.isfinite(e.x) and math.isfinite(e.y)))
    return "%s (%d%s)" % (name, len(events), "; %d at an unknown position" % unknown if unknown else "")


def occupied_bounds(grid):
    """(x_min, x_max, y_min, y_max) in metres of the occupied cells of an OccupancyGrid, or None."""
    import numpy as np
    info = grid.info
    cells = np.asarray(grid.data, dtype=np.int16).reshape(info.height, info.width)
    rows, cols = np.nonzero(cells > 50)
    if not len(rows):
        return None
    x0, y0, res = info.origin.position.x, info.origin.position.y, info.resolution
    return (x0 + cols.min() * res, x0 + (cols.max() + 1) * res, y0 + rows.min() * res, y0 + (rows.max() + 1) * res)


def view_bounds(points, boxes=(), min_margin=6.0):
    """((x_lo, x_hi), (y_lo, y_hi)) of the map view: every finite point and every box (x_min, x_max,
    y_min, y_max; None ignored) plus a margin (``min_margin`` m or 15 % of the size), so the driven
    area and everything the legend lists are drawn, not the whole yard. None when nothing is known."""
    xs = [x for x, y in points if math.isfinite(x) and math.isfinite(y)]
    ys = [y for x, y in points if math.isfinite(x) and math.isfinite(y)]
    for box in boxes:
        if box is not None:
            xs += [box[0], box[1]]
            ys += [box[2], box[3]]
    if not xs:
        return None
    margin = max(min_margin, 0.15 * max(max(xs) - min(xs), max(ys) - min(ys)))
    return (min(xs) - margin, max(xs) + margin), (min(ys) - margin, max(ys) + margin)


def label_offset(x, y, bounds, stacked=0, step=11):
    """(dx, dy, ha, va) in points placing a label next to (x, y) toward the middle of the view, so it
    stays inside the axes: left of a point in the right half, above a point in the lower half.
    ``stacked`` labels already at that spot push this one further away (``step`` points each)."""
    if bounds is None:
        return 6, 6 + step * stacked, "left", "bottom"
    (x_lo, x_hi), (y_lo, y_hi) = bounds
    right = x > (x_lo + x_hi) / 2.0
    low = y < (y_lo + y_hi) / 2.0
    dx, ha = (-8, "right") if right else (8, "left")
    dy, va = (6 + step * stacked, "bottom") if low else (-6 - step * stacked, "top")
    return dx, dy, ha, va


def _label(ax, text, x, y, bounds, stacked, **style):
    if not (math.isfinite(x) and math.isfinite(y)):
        return   # no position: listed in the text and under the plots, not drawn
    dx, dy, ha, va = label_offset(x, y, bounds, stacked)
    ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points", ha=ha, va=va, zorder=6, **style)


def run(argv=None):
    parser = argparse.ArgumentParser(description="Summarise a recorded run and draw it (PNG).")
    parser.add_argument("bags", nargs="+", help="bag files of one run (splits are read in time order)")
    parser.add_argument("--out", help="PNG path (default: <first bag>.png)")
    parser.add_argument("--ns", help="robot namespace when the bag holds several robots")
    parser.add_argument("--no-plot", action="store_true", help="print the summary only")
    parser.add_argument("--check", action="store_true", help="only check that replay.launch can play the bags")
    # roslaunch appends __name:=... and __log:=... when it runs this as a node (replay.launch)
    args = parser.parse_args([a for a in (sys.argv[1:] if argv is None else argv) if ":=" not in a])
    try:
        if args.check:
            print("bag_report: %s" % check_replayable(args.bags, args.ns))
            return 0
        summary, grid, virtual, warnings = read_run(args.bags, args.ns)
    except ReportError as exc:
        print("bag_report: error: %s" % exc, file=sys.stderr)
        return 1
    for warning in warnings:
        print("bag_report: warning: %s" % warning, file=sys.stderr)
    name = os.path.basename(args.bags[0])
    print(format_summary(summary, name))
    if not args.no_plot:
        out = args.out or os.path.splitext(args.bags[0])[0] + ".png"
        try:
            plot_run(summary, grid, virtual, out, "%s: %s, %.1f m" % (name, _duration(summary.duration),
                                                                      summary.distance))
        except OSError as exc:
            print("bag_report: error: cannot write %s: %s" % (out, exc.strerror or exc), file=sys.stderr)
            return 1
        print("picture: %s" % out)
    return 0


def _duration(seconds):
    return "%d min %02d s" % (int(seconds) // 60, int(seconds) % 60)


def main():
    try:
        code = run()
    except BrokenPipeError:   # output piped into `head`: not an error of the bag
        code = 0
    sys.exit(code)
