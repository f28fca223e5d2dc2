# Shapesmith Rig preset, shipped with the extension: ARKit's shapes with the side as an
# `_L`/`_R` suffix (eyeBlink_L, mouthSmile_R), as Face Cap names them.
# Fills the Shape Key Names table with each such name and the ARKit name it means (the sides
# of jawLeft/jawRight and mouthLeft/mouthRight are directions and keep ARKit's spelling),
# and pairs Left/Right shapes by name.
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
for theirs, means in (
    ("browDown_L", "browDownLeft"),
    ("browDown_R", "browDownRight"),
    ("browOuterUp_L", "browOuterUpLeft"),
    ("browOuterUp_R", "browOuterUpRight"),
    ("cheekSquint_L", "cheekSquintLeft"),
    ("cheekSquint_R", "cheekSquintRight"),
    ("eyeBlink_L", "eyeBlinkLeft"),
    ("eyeBlink_R", "eyeBlinkRight"),
    ("eyeLookDown_L", "eyeLookDownLeft"),
    ("eyeLookDown_R", "eyeLookDownRight"),
    ("eyeLookIn_L", "eyeLookInLeft"),
    ("eyeLookIn_R", "eyeLookInRight"),
    ("eyeLookOut_L", "eyeLookOutLeft"),
    ("eyeLookOut_R", "eyeLookOutRight"),
    ("eyeLookUp_L", "eyeLookUpLeft"),
    ("eyeLookUp_R", "eyeLookUpRight"),
    ("eyeSquint_L", "eyeSquintLeft"),
    ("eyeSquint_R", "eyeSquintRight"),
    ("eyeWide_L", "eyeWideLeft"),
    ("eyeWide_R", "eyeWideRight"),
    ("mouthDimple_L", "mouthDimpleLeft"),
    ("mouthDimple_R", "mouthDimpleRight"),
    ("mouthFrown_L", "mouthFrownLeft"),
    ("mouthFrown_R", "mouthFrownRight"),
    ("mouthLowerDown_L", "mouthLowerDownLeft"),
    ("mouthLowerDown_R", "mouthLowerDownRight"),
    ("mouthPress_L", "mouthPressLeft"),
    ("mouthPress_R", "mouthPressRight"),
    ("mouthSmile_L", "mouthSmileLeft"),
    ("mouthSmile_R", "mouthSmileRight"),
    ("mouthStretch_L", "mouthStretchLeft"),
    ("mouthStretch_R", "mouthStretchRight"),
    ("mouthUpperUp_L", "mouthUpperUpLeft"),
    ("mouthUpperUp_R", "mouthUpperUpRight"),
    ("noseSneer_L", "noseSneerLeft"),
    ("noseSneer_R", "noseSneerRight"),
):
    row = settings.name_map.add()
    row.theirs, row.standard = theirs, means
