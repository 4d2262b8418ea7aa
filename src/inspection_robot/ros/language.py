"""The site's language for a node (inspection_robot.i18n): the namespace parameter ``language`` that
core.launch sets and the site file's top-level ``language`` overrides; a value that is not a language,
or a catalogue that cannot be read, stops the node at start-up with the reason (never a silent
English)."""
import rospy

from inspection_robot.i18n import (CATALOGUE_FILE, DEFAULT_LANGUAGE, VOICE_OF, check_language, load_catalogue,
                                   translator)
from inspection_robot.ros.package_share import share_file


def site_language():
    """The site's language, checked (LanguageError otherwise)."""
    return check_language(rospy.get_param("language", DEFAULT_LANGUAGE))


def site_translator():
    """(language, tr) for what this node writes for people (the patrol report)."""
    language = site_language()
    return language, translator(language, load_catalogue(share_file(CATALOGUE_FILE) or CATALOGUE_FILE))


def voice_language(configured):
    """VoiceCmd.language: ``configured`` (a node's ``~voice_language``) when set, else the site's."""
    return configured if configured else VOICE_OF[site_language()]
