# Shapesmith Rig preset, shipped with the extension: Daz Genesis 8.1's FACS morphs as they
# arrive as shape keys (facs_jnt_EyeBlinkLeft, facs_bs_MouthSmileLeft_div2, facs_ctrl_CheekPuff).
# Fills the Shape Key Names table with each and the ARKit shape it means, and pairs
# Left/Right shapes by name. The eye looks, eyeWide, browDown and browOuterUp morphs are
# left out (their prefixes vary between exports); every tool still reads them by their
# ARKit words (facs_jnt_EyeLookUpLeft is eyeLookUpLeft).
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
for theirs, means in (
    ("facs_jnt_EyeBlinkLeft", "eyeBlinkLeft"),
    ("facs_jnt_EyeBlinkRight", "eyeBlinkRight"),
    ("facs_bs_EyeSquintLeft_div2", "eyeSquintLeft"),
    ("facs_bs_EyeSquintRight_div2", "eyeSquintRight"),
    ("facs_ctrl_BrowInnerUp", "browInnerUp"),
    ("facs_ctrl_CheekPuff", "cheekPuff"),
    ("facs_bs_CheekSquintLeft_div2", "cheekSquintLeft"),
    ("facs_bs_CheekSquintRight_div2", "cheekSquintRight"),
    ("facs_bs_NoseSneerLeft_div2", "noseSneerLeft"),
    ("facs_bs_NoseSneerRight_div2", "noseSneerRight"),
    ("facs_jnt_JawForward", "jawForward"),
    ("facs_jnt_JawLeft", "jawLeft"),
    ("facs_jnt_JawOpen", "jawOpen"),
    ("facs_jnt_JawRight", "jawRight"),
    ("facs_bs_MouthClose_div2", "mouthClose"),
    ("facs_bs_MouthFunnel_div2", "mouthFunnel"),
    ("facs_bs_MouthPucker_div2", "mouthPucker"),
    ("facs_bs_MouthLeft_div2", "mouthLeft"),
    ("facs_bs_MouthRight_div2", "mouthRight"),
    ("facs_bs_MouthRollLower_div2", "mouthRollLower"),
    ("facs_bs_MouthRollUpper_div2", "mouthRollUpper"),
    ("facs_bs_MouthShrugLower_div2", "mouthShrugLower"),
    ("facs_bs_MouthShrugUpper_div2", "mouthShrugUpper"),
    ("facs_bs_MouthDimpleLeft_div2", "mouthDimpleLeft"),
    ("facs_bs_MouthDimpleRight_div2", "mouthDimpleRight"),
    ("facs_bs_MouthFrownLeft_div2", "mouthFrownLeft"),
    ("facs_bs_MouthFrownRight_div2", "mouthFrownRight"),
    ("facs_bs_MouthLowerDownLeft_div2", "mouthLowerDownLeft"),
    ("facs_bs_MouthLowerDownRight_div2", "mouthLowerDownRight"),
    ("facs_bs_MouthPressLeft_div2", "mouthPressLeft"),
    ("facs_bs_MouthPressRight_div2", "mouthPressRight"),
    ("facs_bs_MouthSmileLeft_div2", "mouthSmileLeft"),
    ("facs_bs_MouthSmileRight_div2", "mouthSmileRight"),
    ("facs_bs_MouthStretchLeft_div2", "mouthStretchLeft"),
    ("facs_bs_MouthStretchRight_div2", "mouthStretchRight"),
    ("facs_bs_MouthUpperUpLeft_div2", "mouthUpperUpLeft"),
    ("facs_bs_MouthUpperUpRight_div2", "mouthUpperUpRight"),
    ("facs_bs_TongueOut", "tongueOut"),
):
    row = settings.name_map.add()
    row.theirs, row.standard = theirs, means
