"""capture.importers: other tools' captures -> flashbrdf scene folders (scene.json).

  import_colmap(model_dir, images_dir, mesh, out_dir, ...) -> ColmapImport   # COLMAP sparse model
  read_colmap_model(model_dir) -> ColmapModel                              # read and checked

Each importer reads and checks everything first, raises InputError (exit 2) naming the file or
field, and writes its scene folder aside and renames it into place only when complete.
"""

from flashbrdf.capture.importers.colmap import ColmapImport, import_colmap
from flashbrdf.capture.importers.colmap_model import ColmapModel, read_colmap_model

__all__ = ["ColmapImport", "ColmapModel", "import_colmap", "read_colmap_model"]
