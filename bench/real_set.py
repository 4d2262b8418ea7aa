"""The real-photo gauge set (bench/data/real_gauges.json): its tuning/test split and its protocol.

Why a split: a figure measured on the photos a reader was tuned on says nothing about meters it has
never seen (issue #26: 0.56 % FS on the project's own photos, 8.59 % on an independent set). So
every source (a repository: one photographer, one set of meters) belongs to one part, fixed by a
rule nobody can steer after seeing results: ``split_part`` (SHA-1 of the lower-case "owner/name",
odd -> test, even -> tuning). The labels file records each source's part and ``load`` refuses a
file whose record disagrees with the rule. Thresholds, bands and rules of the reader are chosen on
the tuning part only; only the test part's figures count.

Why a protocol: a photo that is both the calibration picture and the live picture reads its own
hand-placed marks back (an oracle). A dial with two or more photos (same ``dial``) is calibrated
on one (its ``calibration`` photo, else the first listed) and each other photo is read through the
robot's path: the calibration box located in the live photo by feature matching, then read
("cross" protocol). A dial with one photo can only be read on its own picture ("same" protocol),
reported apart. Photos with ``excluded`` (a reason) are not scored: they cap one dial's share of
the set (at most 5 %).
"""
import collections
import hashlib
import json
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LABELS = os.path.join(ROOT, "bench", "data", "real_gauges.json")
DISPLAY_LABELS = os.path.join(ROOT, "bench", "data", "real_displays.json")   # displays and counters (issue #42)
DISPLAY_KINDS = ("lit", "dark", "drum")
PARTS = ("tuning", "test")
MAX_DIAL_SHARE = 0.05
# the categories issues #26 and #40 ask figures for: name -> tags that put a photo in it (any of them)
CATEGORIES = collections.OrderedDict([
    ("scale_end", ("at_scale_end",)),
    ("drag_pointer", ("drag_pointer",)),
    ("counterweight_tail", ("needle_tail", "broad_tail")),
    ("off_centre_pivot", ("off_centre_pivot",)),
    ("reversed_or_nonlinear", ("reversed_scale", "nonlinear")),
    ("oblique", ("oblique",)),
])


class LabelError(ValueError):
    pass


def split_part(repo):
    """The part ("tuning" or "test") a source belongs to, from its name alone."""
    return "test" if int(hashlib.sha1(repo.lower().encode("utf-8")).hexdigest(), 16) % 2 else "tuning"


def dial_of(photo):
    return photo.get("dial", photo["id"])


def load(path=LABELS):
    """The labels document, checked: every photo's source listed with the rule's part, ids unique,
    marks and truth well formed, one calibration photo at most per dial."""
    with open(path) as f:
        doc = json.load(f)
    check(doc)
    return doc


def _check_sources(doc):
    """Every source with the rule's part, every photo's id unique and its source, commit, path known."""
    sources = dict((s["repo"], s) for s in doc["sources"])
    for repo, source in sources.items():
        if source.get("part") != split_part(repo):
            raise LabelError("source %s: part %r, the split rule says %r" % (repo, source.get("part"),
                                                                             split_part(repo)))
    seen = set()
    for photo in doc["photos"] + doc.get("negatives", []):
        pid = photo["id"]
        if pid in seen:
            raise LabelError("photo id %s twice" % pid)
        seen.add(pid)
        if photo["repo"] not in sources:
            raise LabelError("photo %s: source %s not in sources" % (pid, photo["repo"]))
        for key in ("commit", "path"):
            if not photo.get(key):
                raise LabelError("photo %s: no %s" % (pid, key))


def check(doc):
    _check_sources(doc)
    for photo in doc["photos"]:
        pid = photo["id"]
        marks = photo.get("marks") or []
        if len(marks) < 2 or any(len(m) != 3 for m in marks):
            raise LabelError("photo %s: marks must be two or more [value, x, y]" % pid)
        values = [float(m[0]) for m in marks]
        ascending = all(b > a for a, b in zip(values, values[1:]))
        descending = all(b < a for a, b in zip(values, values[1:]))
        if not (ascending or descending):
            raise LabelError("photo %s: mark values must be monotonic" % pid)
        if "truth" not in photo or not photo.get("uncertainty", 0) > 0 or float(photo["radius"]) <= 0:
            raise LabelError("photo %s: truth, uncertainty > 0 and radius > 0 needed" % pid)
        low, high = min(values), max(values)
        if not low - 0.02 * (high - low) <= float(photo["truth"]) <= high + 0.02 * (high - low):
            raise LabelError("photo %s: truth %s outside the marks' range" % (pid, photo["truth"]))
    plan(doc)


def load_displays(path=DISPLAY_LABELS):
    """The displays' labels document, checked: sources and ids as for gauges, every photo's kind, the
    text it shows (digits, a minus, a point, leading blanks), its box [x, y, w, h] when given."""
    from inspection_robot.inspection.digital import parse_shown
    with open(path) as f:
        doc = json.load(f)
    _check_sources(doc)
    for photo in doc["photos"]:
        if photo.get("kind") not in DISPLAY_KINDS or not photo.get("device"):
            raise LabelError("photo %s: kind one of %s and a device needed" % (photo["id"], "|".join(DISPLAY_KINDS)))
        try:
            parse_shown(photo["shown"])
        except (KeyError, ValueError) as err:
            raise LabelError("photo %s: %s" % (photo["id"], err))
        if "box" in photo and (len(photo["box"]) != 4 or min(photo["box"][2:]) <= 0):
            raise LabelError("photo %s: box must be [x, y, w, h] with w, h > 0" % photo["id"])
    plan(doc, device_of)
    return doc


def device_of(photo):
    return photo["device"]


def plan(doc, group=dial_of):
    """photo id -> "calibration" (calibrates its dial, not scored), "cross" (read with another photo's
    calibration) or "same" (its dial's only photo: read with its own), for the scored photos;
    ``group``: what makes photos one meter (a gauge's dial, a display's device)."""
    dials = collections.OrderedDict()
    for photo in doc["photos"]:
        if not photo.get("excluded"):
            dials.setdefault(group(photo), []).append(photo)
    roles = {}
    for members in dials.values():
        if len(members) == 1:
            roles[members[0]["id"]] = "same"
            continue
        marked = [p for p in members if p.get("calibration")]
        if len(marked) > 1:
            raise LabelError("dial %s: %d calibration photos" % (group(members[0]), len(marked)))
        reference = (marked or members)[0]
        for photo in members:
            roles[photo["id"]] = "calibration" if photo is reference else "cross"
    return roles


def calibration_photo(doc, photo, group=dial_of):
    """The photo whose picture and labels calibrate ``photo``'s dial (``group``, see plan)."""
    members = [p for p in doc["photos"] if not p.get("excluded") and group(p) == group(photo)]
    marked = [p for p in members if p.get("calibration")]
    return (marked or members)[0]


def part_of(doc, photo):
    return dict((s["repo"], s["part"]) for s in doc["sources"])[photo["repo"]]


def categories_of(photo):
    tags = set(photo.get("tags", []))
    return [name for name, wanted in CATEGORIES.items() if tags & set(wanted)]


def summary(doc):
    """Counts of the set: readings, sources, dials, per part and per category."""
    roles = plan(doc)
    readings = [p for p in doc["photos"] if not p.get("excluded") and roles[p["id"]] != "calibration"]
    out = {"readings": len(readings), "sources": len(set(p["repo"] for p in readings)),
           "dials": len(set(dial_of(p) for p in readings)),
           "cross": len([p for p in readings if roles[p["id"]] == "cross"]),
           "same": len([p for p in readings if roles[p["id"]] == "same"]),
           "excluded": len([p for p in doc["photos"] if p.get("excluded")])}
    per_dial = collections.Counter(dial_of(p) for p in readings)
    dial, most = per_dial.most_common(1)[0] if per_dial else ("", 0)
    out["largest_dial"] = {"dial": dial, "readings": most, "share": round(most / float(max(1, len(readings))), 3),
                           "within_cap": most <= MAX_DIAL_SHARE * len(readings)}
    for part in PARTS:
        mine = [p for p in readings if part_of(doc, p) == part]
        out[part] = {"readings": len(mine), "sources": len(set(p["repo"] for p in mine))}
    out["categories"] = dict((name, len([p for p in readings if name in categories_of(p)])) for name in CATEGORIES)
    return out
