#!/usr/bin/env python3
"""Prepare the real-photo sets the benches score: gauges (bench/bench_inspection.py) or displays and
counters (``--set displays``, bench/bench_displays.py).

The labels (gauges: calibration points, true reading by eye, uncertainty; displays: the text shown,
the digits' box; both: source repository, commit and path) are in bench/data/real_gauges.json and
real_displays.json; the photographs are not in git. This copies each one into the cache directory
(default ~/.cache/inspection_robot/real_gauges or real_displays, or $REAL_GAUGES_DIR /
$REAL_DISPLAYS_DIR) as <id><ext>, taking it from a local git copy of its repository at the
labelled commit:

    scripts/real_gauges.py [--set gauges|displays] [--mirror DIR ...] [--clone] [--cache DIR]

``--mirror DIR``: a directory holding repositories as DIR/<owner>+<name>/repo (the layout of the
code-search mirror) or DIR/<owner>/<name>; ``--clone``: clone missing repositories from GitHub
(needs network). Prints how many photos are ready and which are missing, and the set's size per
part (bench/real_set.py: the tuning/test split); exit 1 when no photo is ready.
"""
import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import real_set  # noqa: E402  (the labels' checks and split)

SETS = {"gauges": (real_set.load, "REAL_GAUGES_DIR", "real_gauges"),
        "displays": (real_set.load_displays, "REAL_DISPLAYS_DIR", "real_displays")}


def default_cache(which="gauges"):
    _load, variable, name = SETS[which]
    return os.environ.get(variable) or os.path.join(os.path.expanduser("~"), ".cache", "inspection_robot", name)


def _git_dir(mirrors, repo):
    owner, name = repo.split("/")
    for base in mirrors:
        for candidate in (os.path.join(base, "%s+%s" % (owner, name), "repo"), os.path.join(base, owner, name)):
            for git_dir in (os.path.join(candidate, ".git"), candidate):
                if os.path.isdir(os.path.join(git_dir, "objects")):
                    return git_dir
    return None


def _clone(cache, repo):
    target = os.path.join(cache, "_repos", repo.replace("/", "+"))
    if not os.path.isdir(target):
        subprocess.check_call(["git", "clone", "--quiet", "--bare", "https://github.com/%s.git" % repo, target])
    return target


def prepare(cache, mirrors, clone, which="gauges"):
    doc = SETS[which][0]()
    os.makedirs(cache, exist_ok=True)
    ready, missing = 0, []
    for entry in doc["photos"] + doc.get("negatives", []):
        out = os.path.join(cache, entry["id"] + os.path.splitext(entry["path"])[1].lower())
        if os.path.isfile(out):
            ready += 1
            continue
        git_dir = _git_dir(mirrors, entry["repo"])
        if git_dir is None and clone:
            git_dir = _clone(cache, entry["repo"])
        if git_dir is None:
            missing.append(entry["id"])
            continue
        try:
            data = subprocess.check_output(["git", "--git-dir", git_dir, "show",
                                            "%s:%s" % (entry["commit"], entry["path"])], stderr=subprocess.PIPE)
        except subprocess.CalledProcessError as err:
            missing.append("%s (%s)" % (entry["id"], err.stderr.decode(errors="replace").strip()))
            continue
        with open(out + ".tmp", "wb") as f:
            f.write(data)
        os.replace(out + ".tmp", out)
        ready += 1
    return ready, missing


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mirror", action="append", default=[], help="directory of local repository copies")
    parser.add_argument("--clone", action="store_true", help="clone missing repositories from GitHub")
    parser.add_argument("--set", default="gauges", choices=sorted(SETS), help="which labelled set")
    parser.add_argument("--cache", help="where the photos go (default: see above)")
    args = parser.parse_args(argv)
    cache = args.cache or default_cache(args.set)
    ready, missing = prepare(cache, args.mirror or ["/work/.mirror"], args.clone, args.set)
    print("%d photos ready in %s" % (ready, cache))
    if args.set == "gauges":
        print(json.dumps(real_set.summary(real_set.load())))
    for item in missing:
        print("missing: %s" % item)
    return 0 if ready else 1


if __name__ == "__main__":
    sys.exit(main())
