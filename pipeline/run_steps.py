"""The steps `run` shares between one material and several (pipeline.run, pipeline.run_materials):
the stage timer, the methods read from the model, one method's prediction written, the reference
photos read before any slow work, and the methods' renders (made together) compared with them."""

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
        self.start(name)
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        self.add(name, time.perf_counter() - start, stages_done=1)
        return result

    def start(self, name):
        """Show that stage `name` begins."""
        if self.bar.disable:  # on stdout: stderr is kept for the one error line of bad input
            print(f"[{name}] ...", flush=True)
        self.bar.set_description(name)

    def add(self, name, seconds, stages_done=0):
        """Count `seconds` more to stage `name`, timed by the caller: stages that take turns,
        as run's render and compares do photo by photo. stages_done advances the bar."""
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds
        self.bar.update(stages_done)

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


def render_and_compare(scene, geometry, renders, spp, out, references, loaded, stages):
    """Render every reference once for all of `renders`, [(name, table, level)], and compare
    each render with the photo: out/<name>/<stem>.exr/.png and the comparison files, and one
    report row per (name, photo), name by name. table: a 2D/3D table, a MaterialMap or a
    DiffuseAlbedoMap; `level=False` (an export's fit of a method's own table) leaves the row out
    of the report's level check. What does not depend on the BRDF is rendered once for all
    (render.render_scene); each render equals its render alone.

    Stages (StageTimer `stages`): "render" for the renders of all names and what they share
    (reading each photo, saving its masks), "compare <name>" for writing that name's render and
    comparing it."""
    brdfs = [table if isinstance(table, (MaterialMap, DiffuseAlbedoMap)) else TabulatedBRDF(table)
             for _, table, _ in renders]
    rows = {name: [] for name, _, _ in renders}
    stages.start("render and compare")
    made = render_scene(scene, brdfs, spp=spp, photos=references, geometry=geometry)
    while True:
        start = time.perf_counter()
        photo, images, mask = next(made, (None, None, None))
        stages.add("render", time.perf_counter() - start)
        if photo is None:
            break
        # the row names files, not arrays: every (photo, method) row held its render, ΔE map
        # and masks (0.5 GB at 24 MP) until the report, which reads them photo by photo. The
        # masks and the photo are the same for every name: saved and read once.
        start = time.perf_counter()
        mask_file, stored, reference, compare_file = scratch_array(out, mask), None, None, None
        if photo.index in loaded:
            stored, measured = loaded[photo.index]
            # spilled (spill_references): its file, read for this photo only
            reference = np.load(stored) if isinstance(stored, Path) else stored
            mask = mask & measured
            compare_file = scratch_array(out, mask)
        stages.add("render", time.perf_counter() - start)   # shared by every name's compare
        for i, (name, _, level) in enumerate(renders):
            start = time.perf_counter()
            image, images[i] = images[i], None  # each render freed once it is compared
            rows[name].append(_write_and_compare(photo, name, image, mask_file, out / name,
                                                 (stored, reference, mask, compare_file), level))
            del image
            stages.add(f"compare {name}", time.perf_counter() - start)
        del images, mask, reference
    stages.add("render", 0.0, stages_done=1 + len(renders))
    return [row for name in rows for row in rows[name]]


def _write_and_compare(photo, name, image, mask_file, out_dir, photo_data, level):
    """Write one render (<stem>.exr, .png) and, where the photo exists, its comparison files;
    returns the report row. photo_data: (stored photo or None, its pixels, the compared
    pixels' mask, that mask's file), the same for every name."""
    write_exr(out_dir / f"{photo.stem}.exr", image)
    write_preview(out_dir / f"{photo.stem}.png", image)
    row = {"photo": photo.stem, "method": name, "render": out_dir / f"{photo.stem}.exr",
           "mask": mask_file}
    stored, reference, compare_mask, compare_file = photo_data
    if reference is None:
        row.update(delta_e_log_mean=None, rel_rmse=None)
        return row
    metrics, delta_e = write_comparison(out_dir, image, reference, compare_mask,
                                        json_name=f"{photo.stem}_compare.json",
                                        png_name=f"{photo.stem}_delta_e.png", return_map=True)
    row.update(metrics, reference=stored,
               delta_e_map=scratch_array(out_dir.parent, delta_e.astype(np.float32)),
               compare_mask=compare_file)
    if level:
        row["level_ratio_rgb"] = level_ratio(image, reference, compare_mask).tolist()
    return row


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
