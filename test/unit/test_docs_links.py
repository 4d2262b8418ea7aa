"""Every relative markdown link of the repository's documents points to a file that exists and, when it
names an anchor, to a heading of that file (GitHub's anchor rules); the README's task links are there."""
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SKIP_DIRS = {".git", "node_modules", "test_logs"}
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
FENCE = re.compile(r"^\s*(```|~~~)")
INLINE_CODE = re.compile(r"(`+)(?:(?!\1).)+?\1")
README_TASKS = {
    "run a patrol": "docs/operator.md#running-a-patrol",
    "set an alarm limit": "docs/operator.md#alarm-limits-normal-and-alarm-bands",
    "write a backend": "docs/interface.md#clients-and-examples",
    "wire a real base": "docs/deployment.md#wiring-a-base-with-a-ros-driver-driver-ros",
}


def markdown_files():
    found = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS and not d.startswith(".venv"))
        found += [os.path.join(folder, f) for f in sorted(files) if f.endswith(".md")]
    return found


def prose_lines(text):
    """(line number, line) outside fenced code blocks."""
    fenced = False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
        elif not fenced:
            yield number, line


def github_anchor(heading):
    """GitHub's anchor of a heading's text: markup dropped, lowercase, punctuation but '-' and '_' removed,
    spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)   # a link's text stays
    text = re.sub(r"<[^>\s]+>", lambda m: m.group(0) if "`" in heading else "", text)
    text = text.replace("`", "").lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    """Every anchor of a markdown file; a repeated heading gets -1, -2 ... as on GitHub."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    seen, result = {}, set()
    for _, line in prose_lines(text):
        match = HEADING.match(line)
        if match:
            base = github_anchor(match.group(2))
            count = seen.get(base, 0)
            seen[base] = count + 1
            result.add(base if count == 0 else "%s-%d" % (base, count))
    return result


def relative_links(path):
    """(line number, target) of every relative link, inline code left out."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    for number, line in prose_lines(text):
        for target in LINK.findall(INLINE_CODE.sub("", line)):
            if not re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):   # http:, https:, mailto: ...
                yield number, target


def test_the_anchor_rules():
    assert github_anchor("Wiring a base with a ROS driver (`driver: ros`)") == \
        "wiring-a-base-with-a-ros-driver-driver-ros"
    assert github_anchor("Preset directory: `<preset_root>/<preset_id>/<YYYYMMDD_HHMMSS>/`") == \
        "preset-directory-preset_rootpreset_idyyyymmdd_hhmmss"
    assert github_anchor("The simulated yard's patrol (`make patrol`)") == "the-simulated-yards-patrol-make-patrol"
    assert github_anchor("Heartbeat and status (status_control)") == "heartbeat-and-status-status_control"


def test_the_documents_are_found():
    names = {os.path.relpath(p, ROOT) for p in markdown_files()}
    assert {"README.md", "docs/operator.md", "docs/deployment.md", "docs/interface.md",
            "docs/development.md"} <= names
    assert not any(n.startswith((".venv", "web/node_modules")) for n in names)


@pytest.mark.parametrize("path", markdown_files(), ids=lambda p: os.path.relpath(p, ROOT))
def test_every_relative_link_resolves(path):
    broken = []
    for number, target in relative_links(path):
        file_part, _, anchor = target.partition("#")
        resolved = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
        where = "%s:%d: %s" % (os.path.relpath(path, ROOT), number, target)
        if not os.path.exists(resolved):
            broken.append(where + " (no such file)")
        elif anchor and resolved.endswith(".md") and anchor not in anchors(resolved):
            broken.append(where + " (no such heading)")
    assert not broken, "\n".join(broken)


def test_the_readme_links_each_task_to_its_section():
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        readme = f.read()
    for task, target in README_TASKS.items():
        assert "[%s](%s)" % (task, target) in readme, task
        file_part, _, anchor = target.partition("#")
        assert anchor in anchors(os.path.join(ROOT, file_part)), target
    # the two commands come first, right after the title
    lines = readme.splitlines()
    assert lines[0].startswith("# ") and lines[2] == "```sh"
    assert lines[3].startswith("make run ") and lines[4].startswith("make test ") and lines[5] == "```"
