"""Does `extract` recover the flash slice of every table? A sweep over whole sets.

    nice -n 10 python -m benchmarks.extract_sweep --merl-dir /work/data/merl [--merl-dir /work/data/rgl]
        [--offset 0.03] [--photons N] [--work DIR]

Every table of each folder (MERL (NBRDF proxy), RGL (NBRDF proxy)) is rendered on a sphere through
the contract's pixel model (tests/synthetic.py: trimesh rays, nearest-bin table lookup), flash at
the lens or `--offset` metres beside it, noise-free unless --photons. slice_extract.extract_slice
then extracts the slice, compared with the table's own θd = 0 row (brdf.views.flash_slice): per
bin the largest relative error over channels, on bins with n >= 20 pixels. The chrome tables span
six decades and the black ones sit near zero: the cases the brief names. Writes
benchmarks/results/extract_sweep.{json,md}.
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks._real_common import RESULTS, write_json

N_MIN = 20


def table_errors(table_path, work, offset, photons, seed):
    """{"median", "p90"}: over bins with n >= N_MIN, the largest per-channel relative error of
    the extracted slice against the table's θd = 0 row; {"log_median", "log_p90"}: the same for
    |Δ ln(ρ + e)|, e = brdf.colour.FEATURE_OFFSET (what inference reads); "bins": how many."""
    from flashbrdf.brdf.colour import FEATURE_OFFSET
    from flashbrdf.brdf.merl import read_merl
    from flashbrdf.brdf.views import flash_slice
    from flashbrdf.slice_extract import extract_slice
    from tests.synthetic import pinhole_camera, point_light, sphere_mesh, table_brdf, write_synthetic_scene
    table = read_merl(table_path)
    truth, _ = flash_slice(table)
    folder = write_synthetic_scene(work / Path(table_path).stem, sphere_mesh(), table_brdf(table),
                                   pinhole_camera(), [point_light([offset, 0, 0])],
                                   photons=photons, seed=seed)
    result = extract_slice(folder)
    ok = (result.n >= N_MIN) & np.all(np.isfinite(truth), axis=1) & np.all(truth > 0, axis=1) \
        & np.all(np.isfinite(result.rho), axis=1)
    rel = np.max(np.abs(result.rho[ok] / truth[ok] - 1), axis=1)
    log = np.max(np.abs(np.log(result.rho[ok] + FEATURE_OFFSET)
                        - np.log(truth[ok] + FEATURE_OFFSET)), axis=1)
    if not rel.size:
        return {"median": float("nan"), "p90": float("nan"), "log_median": float("nan"),
                "log_p90": float("nan"), "bins": 0}
    return {"median": float(np.median(rel)), "p90": float(np.percentile(rel, 90)),
            "log_median": float(np.median(log)), "log_p90": float(np.percentile(log, 90)),
            "bins": int(ok.sum())}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--merl-dir", action="append", required=True)
    ap.add_argument("--offset", type=float, default=0.0, help="flash beside the lens, metres")
    ap.add_argument("--photons", type=int, default=None, help="Poisson noise at the mean pixel")
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--out", default="extract_sweep", help="results name in benchmarks/results")
    args = ap.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="extract_sweep_"))
    work.mkdir(parents=True, exist_ok=True)
    result = {"command": "python -m benchmarks.extract_sweep " + " ".join(argv or sys.argv[1:]),
              "offset_m": args.offset, "photons": args.photons, "tables": {}}
    start = time.perf_counter()
    paths = [p for folder in args.merl_dir for p in sorted(Path(folder).glob("*.binary"))]
    for i, path in enumerate(paths):
        row = table_errors(path, work, args.offset, args.photons, seed=i)
        result["tables"][path.stem] = row
        print(f"{path.stem}: {row}", flush=True)
    result["seconds"] = time.perf_counter() - start
    medians = np.array([t["median"] for t in result["tables"].values()])
    logs = np.array([t["log_p90"] for t in result["tables"].values()])
    result["summary"] = {"tables": len(medians), "median_of_medians": float(np.nanmedian(medians)),
                         "worst": float(np.nanmax(medians)),
                         "log_p90_median": float(np.nanmedian(logs)),
                         "log_p90_worst": float(np.nanmax(logs))}
    write_json(RESULTS / f"{args.out}.json", result)
    worst = sorted(result["tables"].items(), key=lambda kv: -np.nan_to_num(kv[1]["median"]))[:10]
    lines = ["# `extract` against the true flash slice, every table", "",
             f"Command: `{result['command']}` ({result['seconds']:.0f} s). A sphere, flash "
             f"{args.offset * 100:.0f} cm beside the lens, "
             + (f"{args.photons}-photon noise" if args.photons else "noise-free")
             + f"; per bin the largest relative error over channels, bins with n >= {N_MIN}.", "",
             f"- tables: {len(medians)}; median over tables of the per-table median error: "
             f"{result['summary']['median_of_medians']:.4f}; worst table: "
             f"{result['summary']['worst']:.4f}",
             f"- in ln(ρ + 1e-3), the model's feature space, the 90th-percentile bin's error: "
             f"median over tables {result['summary']['log_p90_median']:.4f}, worst "
             f"{result['summary']['log_p90_worst']:.4f}", "",
             "| the 10 worst tables (relative) | median | 90th percentile | ln(ρ + e): median, "
             "90th percentile | bins |", "|---|---|---|---|---|"]
    lines += [f"| {name} | {t['median']:.4f} | {t['p90']:.4f} | {t['log_median']:.4f}, "
              f"{t['log_p90']:.4f} | {t['bins']} |" for name, t in worst]
    (RESULTS / f"{args.out}.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
