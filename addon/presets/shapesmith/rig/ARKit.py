# Shapesmith Rig preset, shipped with the extension: ARKit's own names (eyeBlinkLeft,
# jawOpen, mouthRollUpper), the names every tool reads. Empties the Shape Key Names table
# (a table picked for another rig would rename these) and pairs Left/Right shapes by name.
import bpy

settings = bpy.context.scene.shapesmith
settings.pair_by_name = True
settings.name_map.clear()
