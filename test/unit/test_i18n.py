"""The one catalogue of the console and the report (web/console/strings.json): every word the page
and the report write for people has its zh-CN text, with the same {placeholders}; the translator fills
them in; a language that does not exist is refused."""
import glob
import json
import os
import re
from html.parser import HTMLParser

import pytest

from inspection_robot.i18n import (CATALOGUE_FILE, LANGUAGES, LanguageError, check_language, fill, load_catalogue,
                                   translator)

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
CONSOLE = os.path.join(ROOT, "web", "console")
CATALOGUE = load_catalogue(os.path.join(ROOT, CATALOGUE_FILE))
ZH = CATALOGUE["zh-CN"]
# text of the page that is no word to translate: symbols, units, numbers, example values
NOT_WORDS = re.compile(r"^([^A-Za-z]*|m/s|[A-Z] / [^ ]+|W / ↑|A / ←|S / ↓|D / →)$")


class _Texts(HTMLParser):
    """The text nodes and title/placeholder attributes of index.html, as i18n.js translatePage sees them."""

    def __init__(self):
        super().__init__()
        self.texts, self.stack = [], []

    def handle_starttag(self, tag, attrs):
        self.stack.append(tag)
        for key, value in attrs:
            if key in ("title", "placeholder") and value:
                self.texts.append(" ".join(value.split()))

    def handle_endtag(self, tag):
        if self.stack:
            self.stack.pop()

    def handle_data(self, data):
        text = " ".join(data.split())
        if text and not (self.stack and self.stack[-1] in ("script", "style", "textarea")):
            self.texts.append(text)


def page_texts():
    parser = _Texts()
    with open(os.path.join(CONSOLE, "index.html"), encoding="utf-8") as f:
        parser.feed(f.read())
    return [t for t in parser.texts if not NOT_WORDS.match(t)]


def code_keys():
    """Every literal key of t('...') in the console's modules and tr("...") in the report."""
    keys = []
    for path in glob.glob(os.path.join(CONSOLE, "*.js")):
        with open(path, encoding="utf-8") as f:
            source = f.read()
        keys += [m.replace("\\'", "'") for m in re.findall(r"\bt\(\s*'((?:[^'\\]|\\.)*)'", source)]
        keys += [k for pair in re.findall(r"\bt\(\s*[a-z][^)]*? \? '((?:[^'\\]|\\.)*)' : '((?:[^'\\]|\\.)*)'", source)
                 for k in pair]
    for name in ("report.py", "report_html.py"):
        with open(os.path.join(ROOT, "src", "inspection_robot", "task", name), encoding="utf-8") as f:
            source = f.read()
        for literal in re.findall(r'\btr\(\s*((?:"(?:[^"\\]|\\.)*"\s*)+)', source):
            keys.append("".join(re.findall(r'"((?:[^"\\]|\\.)*)"', literal)))
    return sorted(set(keys))


def test_every_word_of_the_page_and_the_code_has_its_chinese():
    missing = sorted(set(t for t in page_texts() + code_keys() if t not in ZH))
    assert missing == [], "add to web/console/strings.json: %s" % missing


def test_every_translation_keeps_the_placeholders_and_is_chinese():
    for english, chinese in ZH.items():
        assert sorted(re.findall(r"\{(\w+)\}", english)) == sorted(re.findall(r"\{(\w+)\}", chinese)), english
        technical = ("control_cmd disable_stop", "presets/p1/20260101_120000")
        if re.search(r"[a-z]{3}", english) and english not in technical:
            assert re.search(r"[\u4e00-\u9fff]", chinese), (english, chinese)


def test_words_the_code_passes_through_t_have_their_chinese():
    """Words that reach t() as values (robot_status bits, states, kinds...) rather than literals."""
    with open(os.path.join(CONSOLE, "decode.js"), encoding="utf-8") as f:
        decode = f.read()
    tables = decode[decode.index("export const MODES"):decode.index("/** The set bits")]
    words = re.findall(r"'([A-Za-z][^']*)'", re.sub(r"//[^\n]*", "", tables))
    words = [w for w in words if not re.match(r"^[a-z]+_status$", w)]
    states = ["idle", "running", "paused", "returning_home", "done", "cancelled", "failed", "suspended", "routine",
              "special", "shortest", "given", "pointer", "lamp", "switch", "thermal", "digital", "foreign",
              "general", "serious", "critical", "off", "closed", "open", "lit red", "lit green", "connected",
              "link error", "disconnected: reconnecting…", "no link: retrying…", "normal band low", "alarm band high",
              "operator", "charge", "mode", "submit", "pause", "resume", "cancel", "return_home", "7 days", "1 year",
              "normal", "warning", "alarm", "trend", "check (uncertain, outside its band)", "zero", "full scale"]
    assert sorted(set(w for w in words + states if w not in ZH)) == []


def test_the_translator_fills_values_and_keeps_unknown_text():
    tr = translator("zh-CN", CATALOGUE)
    assert tr("Needs attention ({n})", n=3) == "需要关注（3）"
    assert tr("a reason the robot wrote") == "a reason the robot wrote"
    english = translator("en", CATALOGUE)
    assert english("Needs attention ({n})", n=3) == "Needs attention (3)"
    assert fill("{a} and {b}", {"a": 1}) == "1 and {b}"


@pytest.mark.parametrize("bad", ["zh", "fr", "", None, "zh-cn", "en-US"])
def test_a_language_that_does_not_exist_is_refused(bad):
    with pytest.raises(LanguageError, match=r"language must be one of zh-CN\|en, got"):
        check_language(bad)
    with pytest.raises(LanguageError):
        translator(bad, CATALOGUE)


def test_the_catalogue_has_every_language_and_a_broken_one_is_refused(tmp_path):
    assert set(CATALOGUE) == set(LANGUAGES)
    broken = tmp_path / "strings.json"
    broken.write_text("{not json")
    with pytest.raises(LanguageError, match="cannot read the catalogue"):
        load_catalogue(str(broken))
    broken.write_text(json.dumps({"zh-CN": ["a"]}))
    with pytest.raises(LanguageError, match="must be"):
        load_catalogue(str(broken))
