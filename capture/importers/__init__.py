"""importers: other tools' captures written as flashbrdf scene folders (the contract's scene.json).

- colmap: a COLMAP sparse model (text or binary) of flash photos, with a mesh in its frame
  (`flashbrdf import-colmap`): import_colmap(model_dir, images_dir, mesh, out_dir, ...);
  colmap_model reads and checks the model through pycolmap; mesh_frame checks the mesh sits in
  the model's frame.
- diligent: a DiLiGenT photometric-stereo object (`flashbrdf import-diligent`).

Each importer reads and checks everything first, raises InputError (exit 2) naming the file or
field, and writes its scene folder aside and renames it into place only when complete.
"""
