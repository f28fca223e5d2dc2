# Shapesmith Rig preset, shipped with the extension: ARKit's shapes with Blender's side
# suffix `.L`/`.R` (eyeBlink.L, mouthSmile.R). Fills the Shape Key Names table with each such
# name and the ARKit name it means (the sides of jawLeft/jawRight and mouthLeft/mouthRight are
# directions and keep ARKit's spelling), and pairs Left/Right shapes by name.
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
for theirs, means in (
    ("browDown.L", "browDownLeft"),
    ("browDown.R", "browDownRight"),
    ("browOuterUp.L", "browOuterUpLeft"),
    ("browOuterUp.R", "browOuterUpRight"),
    ("cheekSquint.L", "cheekSquintLeft"),
    ("cheekSquint.R", "cheekSquintRight"),
    ("eyeBlink.L", "eyeBlinkLeft"),
    ("eyeBlink.R", "eyeBlinkRight"),
    ("eyeLookDown.L", "eyeLookDownLeft"),
    ("eyeLookDown.R", "eyeLookDownRight"),
    ("eyeLookIn.L", "eyeLookInLeft"),
    ("eyeLookIn.R", "eyeLookInRight"),
    ("eyeLookOut.L", "eyeLookOutLeft"),
    ("eyeLookOut.R", "eyeLookOutRight"),
    ("eyeLookUp.L", "eyeLookUpLeft"),
    ("eyeLookUp.R", "eyeLookUpRight"),
    ("eyeSquint.L", "eyeSquintLeft"),
    ("eyeSquint.R", "eyeSquintRight"),
    ("eyeWide.L", "eyeWideLeft"),
    ("eyeWide.R", "eyeWideRight"),
    ("mouthDimple.L", "mouthDimpleLeft"),
    ("mouthDimple.R", "mouthDimpleRight"),
    ("mouthFrown.L", "mouthFrownLeft"),
    ("mouthFrown.R", "mouthFrownRight"),
    ("mouthLowerDown.L", "mouthLowerDownLeft"),
    ("mouthLowerDown.R", "mouthLowerDownRight"),
    ("mouthPress.L", "mouthPressLeft"),
    ("mouthPress.R", "mouthPressRight"),
    ("mouthSmile.L", "mouthSmileLeft"),
    ("mouthSmile.R", "mouthSmileRight"),
    ("mouthStretch.L", "mouthStretchLeft"),
    ("mouthStretch.R", "mouthStretchRight"),
    ("mouthUpperUp.L", "mouthUpperUpLeft"),
    ("mouthUpperUp.R", "mouthUpperUpRight"),
    ("noseSneer.L", "noseSneerLeft"),
    ("noseSneer.R", "noseSneerRight"),
):
    row = settings.name_map.add()
    row.theirs, row.standard = theirs, means
