"""importers: other capture formats written as scene folders (the contract's scene.json).

- diligent: a DiLiGenT photometric-stereo object (`flashbrdf import-diligent`)
"""
