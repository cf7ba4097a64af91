"""Shared plumbing for the real-photo benchmarks (diligent_ball.py, planar_cards.py).

The stages are driven through the public command line (pipeline.cli.main, in-process), so the
benchmarks depend only on the contract. Where a stage is not built yet, a small direct
implementation of the contract's pixel model stands in for it, and the results say so.
"""

import argparse
import contextlib
import io
import json
import os
import time
from pathlib import Path

import numpy as np

from flashbrdf.brdf.angles import half_diff_from_world, merl_bin_index
from flashbrdf.brdf.lookup import evaluate_table
from flashbrdf.brdf.merl import theta_h_centres

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("FLASHBRDF_SHARED", REPO.parent / "shared"))
RESULTS = REPO / "benchmarks" / "results"
METHODS = "dsgplvm,pca,noll,chandraker,ashikhmin"


def argument_parser(description, data_name, work_name):
    """The options both real-photo benchmarks share: --data (../shared/data/real/DATA_NAME),
    --model, --merl-dir, --methods, --work (/tmp/WORK_NAME). Add the benchmark's own, then parse."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--data", default=SHARED / "data" / "real" / data_name, type=Path)
    ap.add_argument("--model", default=None)
    ap.add_argument("--merl-dir", default=None)
    ap.add_argument("--methods", default=METHODS)
    ap.add_argument("--work", default=Path("/tmp") / work_name, type=Path)
    return ap


def run_cli(argv):
    """Run `flashbrdf ARGV` in-process: (exit status, stderr text, seconds)."""
    from flashbrdf.cli.main import main
    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse rejects an argument
            rc = exc.code
        except Exception as exc:  # a stage crashed: report it, let the caller fall back
            print(f"{type(exc).__name__}: {exc}", file=err)
            rc = 1
    return rc, err.getvalue().strip(), time.perf_counter() - start


def resolve_model(model, merl_dir, work, log=print):
    """The model to infer with: --model, else the committed default (sample_data/models/*.npz),
    else one trained now with `flashbrdf train --merl-dir` into WORK/model.npz, else None."""
    if model:
        return Path(model)
    models = sorted((REPO / "sample_data" / "models").glob("*.npz"))
    if models:
        return models[0]
    if not merl_dir:
        return None
    path = Path(work) / "model.npz"
    if not path.is_file():
        rc, err, seconds = run_cli(["train", "--merl-dir", merl_dir, "--out", path])
        log(f"train on {merl_dir}: exit {rc} in {seconds:.0f} s {err.splitlines()[-1] if err else ''}")
        if rc != 0:
            return None
    return path


def infer_all(slice_csv, out_dir, methods, model=None, merl_dir=None, log=print):
    """{method: (path of BRDF.binary, seconds)} for the methods `flashbrdf infer` can run."""
    out = {}
    for method in methods:
        path = Path(out_dir) / f"{method}.binary"
        argv = ["infer", "--slice", slice_csv, "--out", path, "--method", method]
        if model:
            argv += ["--model", model]
        if merl_dir:
            argv += ["--merl-dir", merl_dir]
        rc, err, seconds = run_cli(argv)
        if rc == 0:
            out[method] = (path, seconds)
            log(f"infer {method}: {seconds:.1f} s")
        else:
            log(f"infer {method}: skipped (exit {rc}: {err.splitlines()[-1] if err else ''})")
    return out


def direct_extract(pixels, wi, wo, normal, light_factor, max_theta_d_deg=10.0):
    """Minimal stand-in for `extract`: rho = pixel / (light_factor * cos_i), per-bin median.

    pixels (N,3); wi, wo, normal (N,3) unit; light_factor (N,3) = E or I / r^2.
    Returns (rho (90,3) NaN where empty, n (90,), spread (90,3) = MAD * 1.4826).
    """
    cos_i = np.einsum("ij,ij->i", wi, normal)
    cos_o = np.einsum("ij,ij->i", wo, normal)
    theta_h, theta_d, phi_d = half_diff_from_world(wi, wo, normal)
    ok = (cos_i > 0.1) & (cos_o > 0.1) & np.all(np.isfinite(pixels), 1) & np.all(pixels > 0, 1) \
        & (np.degrees(theta_d) < max_theta_d_deg)
    rho = pixels[ok] / (light_factor[ok] * cos_i[ok, None])
    bins = merl_bin_index(theta_h[ok], theta_d[ok], phi_d[ok])[0]
    out, n, spread = np.full((90, 3), np.nan), np.zeros(90, int), np.full((90, 3), np.nan)
    order = np.argsort(bins, kind="stable")
    bins, rho = bins[order], rho[order]
    for i, chunk in zip(*_groups(bins, rho)):  # 90 bins at most: a loop over bins, not pixels
        out[i] = np.median(chunk, axis=0)
        spread[i] = 1.4826 * np.median(np.abs(chunk - out[i]), axis=0)
        n[i] = len(chunk)
    return out, n, spread


def _groups(sorted_keys, values):
    keys, starts = np.unique(sorted_keys, return_index=True)
    return keys, np.split(values, starts[1:])


def direct_render(table, wi, wo, normal, light_factor):
    """Stand-in for `render` with one point or directional light, direct only (convex scenes).

    Returns (N,3) = rho(wi, wo) * light_factor * cos_i, the contract's pixel model with V = 1.
    """
    cos_i = np.einsum("ij,ij->i", wi, normal)
    cos_o = np.einsum("ij,ij->i", wo, normal)
    rho = evaluate_table(table, *half_diff_from_world(wi, wo, normal))
    return rho * light_factor * (np.clip(cos_i, 0, None) * (cos_o > 0))[:, None]


def theta_h_deg():
    return np.degrees(theta_h_centres())


def write_json(path, data):
    from flashbrdf.files.atomic import write_text
    from flashbrdf.pipeline.report_data import jsonable
    write_text(path, json.dumps(jsonable(data), indent=1) + "\n")
