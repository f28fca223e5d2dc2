"""The carried keys' looks in a rigger's words: what the native `look_at_keys` measured where
riggers look first (the eyes closing on a blink, the mouth opening on jawOpen and closing on
mouthClose, smooth lid lines, lip contours and keys, no triangle turned over), one line per
finding, for the wrap's report, the batch command and the Wrap panel."""

# A line or a key is called rougher than its reference past this ratio.
ROUGHER = 1.1


def _ratio(value, reference):
    return value / reference if reference and reference > 0.0 else None


def look_lines(looks):
    """Per key, the findings as (line, good) pairs, the keys a rigger checks first first."""
    lines = []
    shapes = looks["shapes"]
    for shape in shapes:
        name = shape["name"]
        if shape.get("eye_gap") is not None:
            closes = "yes" if shape["eyes_close"] else "no"
            turning = _ratio(shape["lid_turning"], shape["template_lid_turning"])
            lid = f"; lid line {turning:.1f}x as bent as the template's" if turning is not None else ""
            lines.append((f"{name}: eyes close: {closes}, gap {100 * shape['eye_gap']:.0f}% of the open eye "
                          f"(template {100 * shape['template_eye_gap']:.0f}%){lid}",
                          bool(shape["eyes_close"]) and (turning is None or turning <= ROUGHER)))
        if shape.get("mouth_opening") is not None:
            opening = _ratio(shape["mouth_opening"], shape["template_mouth_opening"])
            turning = _ratio(shape["lip_turning"], shape["template_lip_turning"])
            lips = f"; lip contour {turning:.1f}x as bent as the template's" if turning is not None else ""
            if opening is not None:
                lines.append((f"{name}: mouth opens {100 * opening:.0f}% as far as the template's (for the face's size){lips}",
                               0.8 <= opening <= 1.25 and (turning is None or turning <= ROUGHER)))
        if shape.get("mouth_closing") is not None:
            reference = shape["template_mouth_closing"]
            lines.append((f"{name}: closes {100 * shape['mouth_closing']:.0f}% of jawOpen's opening "
                          f"(template {100 * reference:.0f}%)",
                          reference is None or shape["mouth_closing"] >= reference - 0.1))
    for shape in shapes:
        if shape["turned_over"]:
            share, reference = shape["turned_over_share"], shape["template_turned_over_share"]
            lines.append((f"{shape['name']}: {shape['turned_over']} triangle(s) turned over, {100 * share:.2g}% of the skin "
                          f"it moves (template {100 * reference:.2g}%)", share <= ROUGHER * reference))
    rough = [(s["name"], s["roughness"] / s["copy_roughness"]) for s in shapes
             if s["copy_roughness"] > 0.0 and s["roughness"] > ROUGHER * s["copy_roughness"]]
    if rough:
        lines.append(("rougher than a plain copy of the wrapped template's keys: "
                      + ", ".join(f"{n} {r:.1f}x" for n, r in sorted(rough, key=lambda x: -x[1])), False))
    else:
        lines.append(("every key as smooth as a plain copy of the wrapped template's", True))
    if not looks["openings"]["eyes"]:
        lines.append(("eyes not measured: the template has no eyeballs or no eyeBlinkLeft/Right", False))
    if looks["openings"]["mouth"] is None:
        lines.append(("mouth not measured: the template's jawOpen parts no lips", False))
    return lines


def store_looks(character, looks):
    """Keeps the findings on the character for the Wrap panel (one per line, a mark first:
    `+` fine, `!` look at it)."""
    character.shapesmith_wrap.looks = "\n".join(("+ " if good else "! ") + line for line, good in look_lines(looks))
