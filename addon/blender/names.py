"""Shape key names across conventions: the one place every tool (Transfer, Wrap, Import
Capture, Analyze Rig's pairing) decides that two names mean the same shape.

A name is reduced to a key `(base, side)`: `base` the shape in lower case without its side,
`side` "L", "R" or None. On the way:
- Blender's duplicate suffixes go (`eyeBlink.L.001` is `eyeBlink.L`);
- the user's table (their name -> the name it stands for, e.g. ARKit's; a shipped Rig preset
  fills it with a convention's names) is read on the name as written, then without the
  prefixes below;
- exporter and namespace prefixes go (`blendShape2.eyeBlinkLeft`, `head_blendShapes.jawOpen`,
  `Char:jawOpen`), and Daz's (`eCTRLEyesClosedL`, `facs_bs_CheekSquintLeft_div2`);
- the name is split into words (camelCase, `_`, `.`, `-`, spaces); a side word (`Left`,
  `LEFT`, `L`, `l`, `right`, ...) last, first or alone among the words is the side, so
  `eyeBlinkLeft`, `eyeBlink_L`, `eyeBlink.L`, `L_eyeBlink`, `EYEBLINK_LEFT` are one shape;
- the remaining words, run together, go through the conventions' equivalents (`EQUIVALENTS`):
  Character Creator (`Eye_Blink_L`, `Brow_Drop_L`, `Mouth_Roll_In_Upper`, `Eye_L_Look_L`),
  Daz (`EyesClosedL`), VRChat's Unified Expressions as its ARKit equivalents
  (`EyeClosedLeft` = `eyeBlinkLeft`, `LipSuckUpper` = `mouthRollUpper`, ...), so every
  convention meets ARKit's base names.
"""

import json
import re

# Blender's `.001` duplicate suffixes, possibly repeated.
_DUPLICATE = re.compile(r"(?:\.\d{3})+$")
# Namespaces (`Char:`, `|group|`) and a blend shape node's name before a dot (`blendShape2.`).
_EXPORTER = re.compile(r"^(?:[^.:|]*[:|])*(?:[^.:|]*blend_?shapes?[^.:|]*\.)?", re.IGNORECASE)
# Daz morph prefixes and the `_div2` suffix of its FACS halves.
_DAZ_PREFIX = re.compile(r"^(?:eCTRL|CTRL|PHM|facs_(?:jnt|bs|ctrl|cbs)_)")
_DAZ_SUFFIX = re.compile(r"_div\d+$", re.IGNORECASE)
_WORDS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+")
_SIDES = {"l": "L", "left": "L", "r": "R", "right": "R"}

# Whole names (words run together, side included) whose side word sits in the middle:
# Character Creator's eye looks name the eye, then the direction.
WHOLE_NAMES = {
    "eyellookup": ("eyelookup", "L"), "eyellookdown": ("eyelookdown", "L"),
    "eyellookl": ("eyelookout", "L"), "eyellookr": ("eyelookin", "L"),
    "eyerlookup": ("eyelookup", "R"), "eyerlookdown": ("eyelookdown", "R"),
    "eyerlookl": ("eyelookin", "R"), "eyerlookr": ("eyelookout", "R"),
}

# Each convention's base names (side removed) for ARKit's.
EQUIVALENTS = {
    "Character Creator": {
        "browdrop": "browdown", "browraiseinner": "browinnerup", "browraiseouter": "browouterup",
        "cheekraise": "cheeksquint", "mouthupupper": "mouthupperup", "mouthdownlower": "mouthlowerdown",
        "mouthrollinupper": "mouthrollupper", "mouthrollinlower": "mouthrolllower",
    },
    "Daz": {"eyesclosed": "eyeblink", "eyessquint": "eyesquint", "eyeswide": "eyewide"},
    "Unified Expressions": {
        "eyeclosed": "eyeblink", "browlowerer": "browdown", "lipsuckupper": "mouthrollupper",
        "lipsucklower": "mouthrolllower", "lipfunnel": "mouthfunnel", "lippucker": "mouthpucker",
        "mouthclosed": "mouthclose", "mouthraiserupper": "mouthshrugupper", "mouthraiserlower": "mouthshruglower",
        "mouthcornerpull": "mouthsmile",
    },
}
_BASES = {alias: base for table in EQUIVALENTS.values() for alias, base in table.items()}


def bare(name):
    """`name` without Blender's duplicate suffix and exporters' and Daz's prefixes."""
    name = _DUPLICATE.sub("", name.strip())
    name = _EXPORTER.sub("", name) or name
    return _DAZ_SUFFIX.sub("", _DAZ_PREFIX.sub("", name) or name)


def _meant(name, table):
    """What `name` stands for in the user's table: its row as spelled, else in any case (None: no row)."""
    if name in table:
        return table[name]
    return {k.lower(): v for k, v in table.items()}.get(name.lower())


def shape_key(name, table=None):
    """(base, side) of a shape name (the module's header); `table`: the user's names
    ({their name: the name it stands for}), matched on the name as written (without Blender's
    duplicate suffix: `facs_bs_MouthSmileLeft_div2`), then on its bare name (`MouthSmileLeft`)."""
    written = _DUPLICATE.sub("", name.strip())
    name = bare(name)
    meant = table and (_meant(written, table) or _meant(name, table))
    if meant:
        name = bare(meant)
    words = [w.lower() for w in _WORDS.findall(name)]
    whole = "".join(words)
    if whole in WHOLE_NAMES:
        return WHOLE_NAMES[whole]
    side = None
    sides = [i for i, w in enumerate(words) if w in _SIDES]
    if len(words) > 1 and sides:
        if sides[-1] == len(words) - 1:
            side = _SIDES[words.pop()]
        elif sides[0] == 0:
            side = _SIDES[words.pop(0)]
        elif len(sides) == 1:
            side = _SIDES[words.pop(sides[0])]
    base = "".join(words) or name.lower()
    return _BASES.get(base, base), side


def pairing_name(name, table=None):
    """The name in one spelling (`<base>Left`, `<base>Right`, `<base>`), which Analyze Rig's
    pairing by name reads whatever the rig's convention."""
    base, side = shape_key(name, table)
    return base + {"L": "Left", "R": "Right", None: ""}[side]


def same_shape(name, candidates, table=None):
    """The names among `candidates` that mean the shape `name`: itself when there, else
    every candidate with its key."""
    if name in candidates:
        return [name]
    key = shape_key(name, table)
    return [c for c in candidates if shape_key(c, table) == key]


def counterpart(name, candidates, table=None):
    """The one name among `candidates` meaning the shape `name` (itself first), or None when
    none or several do."""
    found = same_shape(name, candidates, table)
    return found[0] if len(found) == 1 else None


def read_name_map(text, what="the name map"):
    """A user table from text: a JSON object {"their name": "name it stands for"}, or lines
    `their name = name it stands for` (or comma separated), `#` starting a comment."""
    text = text.strip()
    if text.startswith("{"):
        try:
            table = json.loads(text)
        except json.JSONDecodeError as error:
            raise ValueError(f"{what} is not valid JSON: {error}")
        if not all(isinstance(v, str) for v in table.values()):
            raise ValueError(f'{what} must map names to names: {{"EyeBlink_L": "eyeBlinkLeft"}}')
        return table
    table = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p.strip() for p in re.split(r"[=,\t]", line, maxsplit=1)]
        if len(parts) != 2 or not all(parts):
            raise ValueError(f"{what} line {number} is not 'their name = name it stands for': {line!r}")
        table[parts[0]] = parts[1]
    return table


def text_name_map(text, what="the driver map"):
    """`read_name_map` of a Blender Text (None for none)."""
    return read_name_map(text.as_string(), f"{what} '{text.name}'") if text is not None else None


def scene_name_map(scene):
    """The user's table from the Names panel (rows with both names filled)."""
    rows = getattr(scene.shapesmith, "name_map", ())
    return {row.theirs.strip(): row.standard.strip() for row in rows if row.theirs.strip() and row.standard.strip()}
