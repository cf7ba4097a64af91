"""The steps `run` shares between one material and several (pipeline.run, pipeline.run_materials):
the stage timer, the methods read from the model, one method's prediction written, the reference
photos read before any slow work, and one method's renders compared with them."""

import shutil
import sys
import time
import uuid
from pathlib import Path

import numpy as np
from tqdm import tqdm

from flashbrdf import capture
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.infer.prediction import brdf_record, predict_slice, write_prediction
from flashbrdf.render import (DiffuseAlbedoMap, MaterialMap, level_ratio, render_scene,
                              write_comparison, write_exr, write_preview)
from flashbrdf.render.envmap import read_envmap_pixels


class StageTimer:
    """Wall-clock seconds per stage, in run order, printed as a table at the end.

    On a terminal a progress bar counts the stages (renders add their own per-photo bars);
    otherwise each stage prints one line on stdout, which keeps logs readable.
    """

    def __init__(self, total):
        self.seconds = {}
        self.bar = tqdm(total=total, unit="stage", file=sys.stderr, disable=not sys.stderr.isatty())

    def run(self, name, fn, *args, **kwargs):
        if self.bar.disable:  # on stdout: stderr is kept for the one error line of bad input
            print(f"[{name}] ...", flush=True)
        self.bar.set_description(name)
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start
        self.bar.update(1)
        return result

    def table(self):
        width = max(len(k) for k in self.seconds) if self.seconds else 5
        lines = [f"{'stage':<{width}}  seconds", f"{'-' * width}  -------"]
        lines += [f"{k:<{width}}  {v:7.2f}" for k, v in self.seconds.items()]
        lines.append(f"{'total':<{width}}  {sum(self.seconds.values()):7.2f}")
        return "\n".join(lines)


def reference_outputs(stem):
    """The files render and run write for one reference photo (in OUT_DIR, or OUT_DIR/<method>)."""
    return [f"{stem}.exr", f"{stem}.png", f"{stem}_compare.json", f"{stem}_delta_e.png"]


def load_methods(names, model_path, anchor):
    """{name: fitted method}, the model file read once for all of them."""
    from flashbrdf.infer import make_method
    from flashbrdf.infer.model_file import load_methods as read_methods
    if model_path is None:
        return {name: make_method(name).fit(None) for name in names}
    return read_methods(model_path, names, overrides={"dsgplvm": {"anchor": anchor}})


def infer_method(method, name, model, rho, n, out_dir, level=None):
    """One method's prediction from the slice, written to out_dir/brdf.binary + brdf.json; the
    prediction (infer.prediction.Prediction). 3D where the model stores 3D data, else 2D."""
    view = "3d" if method.training_3d() == "stored" else "2d"
    prediction = predict_slice(method, rho, n, view, source=name)
    write_prediction(out_dir / "brdf.binary", prediction,
                     brdf_record(prediction, method, name, model, level))
    return prediction


def check_references(references):
    """Read every reference photo and environment map `run` will need, before any slow work:
    bad input (unreadable, wrong size, not lat-long) fails in seconds, not after inference.

    Returns {photo index: (rgb, measured)} for the photos that exist (render compares with them
    over the object's measured pixels: capture.load_reference_entry).
    """
    loaded = {}
    for photo in references:
        if photo.light is not None and photo.light.type == "envmap":
            read_envmap_pixels(photo.light.file)
        if capture.photo_exists(photo):
            loaded[photo.index] = capture.load_reference_entry(photo)
    return loaded


def render_and_compare(scene, geometry, method_name, table, spp, out_dir, references, loaded,
                       level=True):
    """Render and compare every reference for one method: <stem>.exr/.png and the comparison files
    in out_dir, and one report row per photo. table: a 2D/3D table, a MaterialMap or a
    DiffuseAlbedoMap; `level=False` (an export's fit of a method's own table) leaves the row out
    of the report's level check."""
    rows = []
    brdf = table if isinstance(table, (MaterialMap, DiffuseAlbedoMap)) else TabulatedBRDF(table)
    for photo, image, mask in render_scene(scene, brdf, spp=spp, photos=references,
                                           geometry=geometry):
        write_exr(out_dir / f"{photo.stem}.exr", image)
        write_preview(out_dir / f"{photo.stem}.png", image)
        # the row names files, not arrays: every (photo, method) row held its render, ΔE map
        # and masks (0.5 GB at 24 MP) until the report, which reads them photo by photo
        row = {"photo": photo.stem, "method": method_name, "render": out_dir / f"{photo.stem}.exr",
               "mask": scratch_array(out_dir.parent, mask)}
        if photo.index in loaded:
            stored, measured = loaded[photo.index]
            # spilled (spill_references): its file, read for this photo only
            reference = np.load(stored) if isinstance(stored, Path) else stored
            metrics, delta_e = write_comparison(out_dir, image, reference, mask & measured,
                                                json_name=f"{photo.stem}_compare.json",
                                                png_name=f"{photo.stem}_delta_e.png",
                                                return_map=True)
            row.update(metrics, reference=stored,
                       delta_e_map=scratch_array(out_dir.parent, delta_e.astype(np.float32)),
                       compare_mask=scratch_array(out_dir.parent, mask & measured))
            if level:
                row["level_ratio_rgb"] = level_ratio(image, reference, mask & measured).tolist()
            del delta_e, reference
        else:
            row.update(delta_e_log_mean=None, rel_rmse=None)
        rows.append(row)
        del image, mask
    return rows


SCRATCH = ".report_scratch"  # beside the methods' folders in run's output; gone before it is


def scratch_array(out, array):
    """Save an array for the report into OUT/.report_scratch/ and return its path
    (pipeline.report_data.read_image reads it back, memory-mapped)."""
    folder = Path(out) / SCRATCH
    folder.mkdir(exist_ok=True)
    path = folder / f"{uuid.uuid4().hex}.npy"
    np.save(path, array)
    return path


def spill_references(loaded, out):
    """Right after the output folder is staged: each reference photo goes to
    OUT/.report_scratch/ and `loaded` names the file, so render_and_compare and the report read
    one photo at a time instead of every photo being held from the start (0.3 GB each at 24 MP);
    the rows name the same files."""
    for index, (rgb, measured) in list(loaded.items()):
        loaded[index] = (scratch_array(out, rgb), measured)


def drop_scratch(out):
    """Remove OUT/.report_scratch/ once the report is written."""
    shutil.rmtree(Path(out) / SCRATCH, ignore_errors=True)
