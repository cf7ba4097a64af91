"""scene.json as the importers write it: indented, each innermost list of numbers on one line."""

import json
import re

_NUMBER_LIST = re.compile(r"\[\s*(-?[\d.eE+-]+(?:,\s*-?[\d.eE+-]+)*)\s*\]")


def dumps_scene(scene):
    """scene dict -> JSON text, indented, every innermost list of numbers (a pose row, an
    intensity) on one line so the file reads as the matrices it holds."""
    text = json.dumps(scene, indent=1)
    return _NUMBER_LIST.sub(lambda m: "[" + re.sub(r"\s+", " ", m.group(1)) + "]", text) + "\n"
