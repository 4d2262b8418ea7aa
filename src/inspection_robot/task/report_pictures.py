"""The pictures of a patrol report: one picture per camera view of a preset with every box on it, and
a meter's sparkline.

read_scale writes an annotated copy of the whole frame per target, so a preset of four meters has
four near-identical pictures. The report shows instead the picture read_scale read (a row's
``source_picture``) once, with every target's box (its ``roi``) drawn over it as an SVG polygon in
the reading's state colour and numbered as in the table beside it. A visible view and a thermal
frame are different pictures: thermal boxes go on the first of their annotated pictures (the raw
temperature frame read is no picture a browser shows; the annotated one is it colour-mapped, same
size); rows without a source (older rows, the foreign-object row) show their annotated pictures,
each once.
"""
import html
import os

from inspection_robot.lazy import lazy_import

cv2 = lazy_import("cv2")

BROWSER_PICTURES = (".jpg", ".jpeg", ".png")


def picture_size(path):
    """(width, height) of the picture at ``path``, or None when it cannot be read."""
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED) if os.path.isfile(path) else None
    return None if image is None else (image.shape[1], image.shape[0])


def _roi(text):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        return None
    return values if len(values) == 8 else None


def _overlay(link, size, boxes, alt):
    """An inline SVG of the picture at ``link`` (``size`` px) with ``boxes`` [(number, roi, colour, title)]."""
    width, height = size
    stroke = max(width, height) / 400.0
    parts = ['<svg class="view" viewBox="0 0 %d %d" role="img" aria-label="%s"><image href="%s" width="%d" '
             'height="%d"/>' % (width, height, html.escape(alt), html.escape(link), width, height)]
    for number, roi, colour, title in boxes:
        points = " ".join("%.1f,%.1f" % (roi[i], roi[i + 1]) for i in range(0, 8, 2))
        x, y = min(roi[0::2]), min(roi[1::2])
        font = max(width, height) / 40.0
        parts.append('<g><title>%s</title><polygon points="%s" fill="none" stroke="%s" stroke-width="%.1f"/>'
                     '<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" fill="%s"/><text x="%.1f" y="%.1f" '
                     'font-size="%.1f" fill="#fff" font-weight="bold">%d</text></g>'
                     % (html.escape(title), points, colour, stroke, x, max(0.0, y - font * 1.2), font * 1.1,
                        font * 1.2, colour, x + font * 0.25, max(font, y - font * 0.25), font, number))
    parts.append("</svg>")
    return "".join(parts)


def preset_figures(rows, link_of, colour_of, data_root):
    """The HTML of a preset's pictures: ``rows`` its readings (client rows, in table order, numbered
    from 1), ``link_of(picture)`` a picture's href from the report, ``colour_of(row)`` a box's colour,
    ``data_root`` what relative pictures are relative to. One view per picture read (its boxes on
    it); a raw thermal frame is shown by its first annotated picture (same size, colour-mapped)."""
    views, annotated = [], []
    for number, row in enumerate(rows, 1):
        source, roi = row.get("source_picture") or "", _roi(row.get("roi") or "")
        viewable = source.lower().endswith(BROWSER_PICTURES) and row["kind"] != "thermal"
        background = source if viewable else row.get("picture") or ""
        if source and roi and background:
            view = next((v for v in views if v["source"] == source), None)
            if view is None:
                view = {"source": source, "background": background, "boxes": [], "rows": []}
                views.append(view)
            view["boxes"].append((number, roi, colour_of(row), "%d %s" % (number, row["target_name"])))
            view["rows"].append(row)
        elif row.get("picture") and row["picture"] not in annotated:
            annotated.append(row["picture"])
    out = []
    for view in views:
        size = picture_size(os.path.join(data_root, view["background"]))
        if size is None:   # the picture is gone or unreadable: the annotated pictures instead
            annotated.extend(r["picture"] for r in view["rows"] if r.get("picture") and r["picture"] not in annotated)
            continue
        link = link_of(view["background"])
        overlay = _overlay(link, size, view["boxes"], os.path.basename(view["background"]))
        out.append('<a href="%s">%s</a>' % (html.escape(link), overlay))
    for p in annotated:
        link = html.escape(link_of(p))
        out.append('<a href="%s"><img src="%s" alt="%s"></a>' % (link, link, html.escape(os.path.basename(p))))
    return "".join(out) or '<p class="why">no picture</p>'


SPARK_W, SPARK_H = 90, 24


def sparkline(points, band=None):
    """A small inline SVG of a meter's recent values (oldest first), its band's limits dashed; ""
    for fewer than two points."""
    if len(points) < 2:
        return ""
    values = [v for _t, v in points] + [b for b in (band or ()) if b is not None]
    lo, hi = min(values), max(values)
    span = (hi - lo) or 1.0
    t0, t1 = points[0][0], points[-1][0]

    def xy(t, v):
        return (2 + (t - t0) / ((t1 - t0) or 1.0) * (SPARK_W - 4), SPARK_H - 2 - (v - lo) / span * (SPARK_H - 4))
    lines = "".join('<line x1="0" y1="%.1f" x2="%d" y2="%.1f" stroke="#c62828" stroke-dasharray="2,2"/>'
                    % (xy(t0, b)[1], SPARK_W, xy(t0, b)[1]) for b in (band or ()) if b is not None)
    path = " ".join("%.1f,%.1f" % xy(t, v) for t, v in points)
    return ('<svg class="trend" width="%d" height="%d" viewBox="0 0 %d %d">%s<polyline fill="none" stroke="#1565c0" '
            'points="%s"/></svg>' % (SPARK_W, SPARK_H, SPARK_W, SPARK_H, lines, path))
