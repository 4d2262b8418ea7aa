"""The operator's language for what the robot writes for people: the patrol report (the console has its
own copy of the lookup, web/console/i18n.js, over the same catalogue).

One catalogue, ``web/console/strings.json`` ({language: {English text: text}}), for the console and the
report: the English text is the key (gettext style) and ``{name}`` marks a value put in. The site
chooses the language (the site file's top-level ``language``: ``zh-CN`` or ``en``; the namespace
parameter ``language``); voice prompts follow it (``voice_language`` of the site's language). The
interface's own strings (result rows, reasons, states) stay English: a backend parses them.
"""
import json
import os
import re

LANGUAGES = ("zh-CN", "en")
DEFAULT_LANGUAGE = "zh-CN"
# VoiceCmd.language for each (the spec's words)
VOICE_OF = {"zh-CN": "chinese", "en": "english"}
CATALOGUE_FILE = os.path.join("web", "console", "strings.json")   # under the package's root
_PLACE = re.compile(r"\{(\w+)\}")


class LanguageError(ValueError):
    """A language that is not one of LANGUAGES, or a catalogue that cannot be read."""


def check_language(value):
    """``value`` if it is one of LANGUAGES, else LanguageError naming them."""
    if value not in LANGUAGES:
        raise LanguageError("language must be one of %s, got %r" % ("|".join(LANGUAGES), value))
    return value


def fill(text, params):
    """``text`` with each {name} replaced by ``params[name]`` (a name not given stays as written)."""
    return _PLACE.sub(lambda m: str(params[m.group(1)]) if m.group(1) in params else m.group(0), text)


def load_catalogue(path):
    """The catalogue at ``path``: {language: {English: text}}; LanguageError when unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            catalogue = json.load(f)
    except (OSError, ValueError) as err:
        raise LanguageError("cannot read the catalogue %s: %s" % (path, err))
    if not isinstance(catalogue, dict) or not all(isinstance(v, dict) for v in catalogue.values()):
        raise LanguageError("catalogue %s must be {language: {English text: text}}" % path)
    return catalogue


def translator(language, catalogue):
    """``tr(text, **params)``: ``text`` (English) in ``language``, its {name}s filled in."""
    strings = {} if language == "en" else catalogue.get(check_language(language), {})

    def tr(text, **params):
        return fill(strings.get(text, text), params)
    return tr


def ENGLISH(text, **params):   # noqa: N802 (a translator, used like a constant)
    """The identity translator: English as written."""
    return fill(text, params)
