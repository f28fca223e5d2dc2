# Shapesmith Rig preset, shipped with the extension: VRChat's Unified Expressions (VRCFaceTracking)
# by the ARKit equivalents its documentation lists (EyeClosedLeft is eyeBlinkLeft,
# LipSuckUpper is mouthRollUpper, MouthRaiserUpper is mouthShrugUpper, MouthClosed is
# mouthClose). Fills the Shape Key Names table with each and pairs Left/Right shapes by name.
# mouthLeft/mouthRight have no one-shape equivalent there (MouthUpperLeft with
# MouthLowerLeft) and are left out.
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
for theirs, means in (
    ("BrowDownLeft", "browDownLeft"),
    ("BrowDownRight", "browDownRight"),
    ("BrowInnerUp", "browInnerUp"),
    ("BrowOuterUpLeft", "browOuterUpLeft"),
    ("BrowOuterUpRight", "browOuterUpRight"),
    ("CheekPuff", "cheekPuff"),
    ("CheekSquintLeft", "cheekSquintLeft"),
    ("CheekSquintRight", "cheekSquintRight"),
    ("EyeClosedLeft", "eyeBlinkLeft"),
    ("EyeClosedRight", "eyeBlinkRight"),
    ("EyeLookDownLeft", "eyeLookDownLeft"),
    ("EyeLookDownRight", "eyeLookDownRight"),
    ("EyeLookInLeft", "eyeLookInLeft"),
    ("EyeLookInRight", "eyeLookInRight"),
    ("EyeLookOutLeft", "eyeLookOutLeft"),
    ("EyeLookOutRight", "eyeLookOutRight"),
    ("EyeLookUpLeft", "eyeLookUpLeft"),
    ("EyeLookUpRight", "eyeLookUpRight"),
    ("EyeSquintLeft", "eyeSquintLeft"),
    ("EyeSquintRight", "eyeSquintRight"),
    ("EyeWideLeft", "eyeWideLeft"),
    ("EyeWideRight", "eyeWideRight"),
    ("JawForward", "jawForward"),
    ("JawLeft", "jawLeft"),
    ("JawOpen", "jawOpen"),
    ("JawRight", "jawRight"),
    ("MouthClosed", "mouthClose"),
    ("MouthDimpleLeft", "mouthDimpleLeft"),
    ("MouthDimpleRight", "mouthDimpleRight"),
    ("MouthFrownLeft", "mouthFrownLeft"),
    ("MouthFrownRight", "mouthFrownRight"),
    ("LipFunnel", "mouthFunnel"),
    ("MouthLowerDownLeft", "mouthLowerDownLeft"),
    ("MouthLowerDownRight", "mouthLowerDownRight"),
    ("MouthPressLeft", "mouthPressLeft"),
    ("MouthPressRight", "mouthPressRight"),
    ("LipPucker", "mouthPucker"),
    ("LipSuckLower", "mouthRollLower"),
    ("LipSuckUpper", "mouthRollUpper"),
    ("MouthRaiserLower", "mouthShrugLower"),
    ("MouthRaiserUpper", "mouthShrugUpper"),
    ("MouthSmileLeft", "mouthSmileLeft"),
    ("MouthSmileRight", "mouthSmileRight"),
    ("MouthStretchLeft", "mouthStretchLeft"),
    ("MouthStretchRight", "mouthStretchRight"),
    ("MouthUpperUpLeft", "mouthUpperUpLeft"),
    ("MouthUpperUpRight", "mouthUpperUpRight"),
    ("NoseSneerLeft", "noseSneerLeft"),
    ("NoseSneerRight", "noseSneerRight"),
    ("TongueOut", "tongueOut"),
):
    row = settings.name_map.add()
    row.theirs, row.standard = theirs, means
