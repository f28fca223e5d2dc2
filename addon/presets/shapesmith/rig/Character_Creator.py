# Shapesmith Rig preset, shipped with the extension: Character Creator 4's face morphs
# (Eye_Blink_L, Brow_Drop_L, Cheek_Raise_L, Eye_L_Look_R). Fills the Shape Key Names table
# with each and the ARKit shape it means. Where Character Creator splits an ARKit shape
# (browInnerUp, cheekPuff, mouthRollUpper, mouthRollLower into _L/_R halves; mouthPucker into
# upper and lower halves of each side; mouthFunnel's upper halves), a part means that
# shape's side (`mouthPucker_L`): a capture's mouthPucker drives all four parts. Pairs
# Left/Right shapes by name.
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
for theirs, means in (
    ("Brow_Drop_L", "browDownLeft"),
    ("Brow_Drop_R", "browDownRight"),
    ("Brow_Raise_Inner_L", "browInnerUp_L"),
    ("Brow_Raise_Inner_R", "browInnerUp_R"),
    ("Brow_Raise_Outer_L", "browOuterUpLeft"),
    ("Brow_Raise_Outer_R", "browOuterUpRight"),
    ("Cheek_Puff_L", "cheekPuff_L"),
    ("Cheek_Puff_R", "cheekPuff_R"),
    ("Cheek_Raise_L", "cheekSquintLeft"),
    ("Cheek_Raise_R", "cheekSquintRight"),
    ("Eye_Blink_L", "eyeBlinkLeft"),
    ("Eye_Blink_R", "eyeBlinkRight"),
    ("Eye_L_Look_Down", "eyeLookDownLeft"),
    ("Eye_R_Look_Down", "eyeLookDownRight"),
    ("Eye_L_Look_R", "eyeLookInLeft"),
    ("Eye_R_Look_L", "eyeLookInRight"),
    ("Eye_L_Look_L", "eyeLookOutLeft"),
    ("Eye_R_Look_R", "eyeLookOutRight"),
    ("Eye_L_Look_Up", "eyeLookUpLeft"),
    ("Eye_R_Look_Up", "eyeLookUpRight"),
    ("Eye_Squint_L", "eyeSquintLeft"),
    ("Eye_Squint_R", "eyeSquintRight"),
    ("Eye_Wide_L", "eyeWideLeft"),
    ("Eye_Wide_R", "eyeWideRight"),
    ("Jaw_Forward", "jawForward"),
    ("Jaw_L", "jawLeft"),
    ("Jaw_Open", "jawOpen"),
    ("Jaw_R", "jawRight"),
    ("Mouth_Close", "mouthClose"),
    ("Mouth_Dimple_L", "mouthDimpleLeft"),
    ("Mouth_Dimple_R", "mouthDimpleRight"),
    ("Mouth_Frown_L", "mouthFrownLeft"),
    ("Mouth_Frown_R", "mouthFrownRight"),
    ("Mouth_Funnel_Up_L", "mouthFunnel_L"),
    ("Mouth_Funnel_Up_R", "mouthFunnel_R"),
    ("Mouth_L", "mouthLeft"),
    ("Mouth_R", "mouthRight"),
    ("Mouth_Down_Lower_L", "mouthLowerDownLeft"),
    ("Mouth_Down_Lower_R", "mouthLowerDownRight"),
    ("Mouth_Press_L", "mouthPressLeft"),
    ("Mouth_Press_R", "mouthPressRight"),
    ("Mouth_Pucker_Up_L", "mouthPucker_L"),
    ("Mouth_Pucker_Up_R", "mouthPucker_R"),
    ("Mouth_Pucker_Down_L", "mouthPucker_L"),
    ("Mouth_Pucker_Down_R", "mouthPucker_R"),
    ("Mouth_Roll_In_Lower_L", "mouthRollLower_L"),
    ("Mouth_Roll_In_Lower_R", "mouthRollLower_R"),
    ("Mouth_Roll_In_Upper_L", "mouthRollUpper_L"),
    ("Mouth_Roll_In_Upper_R", "mouthRollUpper_R"),
    ("Mouth_Shrug_Lower", "mouthShrugLower"),
    ("Mouth_Shrug_Upper", "mouthShrugUpper"),
    ("Mouth_Smile_L", "mouthSmileLeft"),
    ("Mouth_Smile_R", "mouthSmileRight"),
    ("Mouth_Stretch_L", "mouthStretchLeft"),
    ("Mouth_Stretch_R", "mouthStretchRight"),
    ("Mouth_Up_Upper_L", "mouthUpperUpLeft"),
    ("Mouth_Up_Upper_R", "mouthUpperUpRight"),
    ("Nose_Sneer_L", "noseSneerLeft"),
    ("Nose_Sneer_R", "noseSneerRight"),
    ("Tongue_Out", "tongueOut"),
):
    row = settings.name_map.add()
    row.theirs, row.standard = theirs, means
