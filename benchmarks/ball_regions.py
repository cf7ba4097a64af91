"""Where on the DiLiGenT ball the default method loses to the best baseline: region swaps.

    PYTHONPATH=$PWD python benchmarks/diligent_ball.py --model MODEL --merl-dir DIR --work WORK
    PYTHONPATH=$PWD python benchmarks/ball_regions.py --work WORK [--against ashikhmin]

Reads the work folder of benchmarks/diligent_ball.py (its imported scene and the methods' predicted
tables WORK/<method>.binary). For one region of the table at a time (a band of θd or of θh
bins), the dsgplvm table takes the other method's values there, and the 95 reference lights are
rendered again with the benchmark's direct pixel model: the drop in ΔE-log mean is what that
region costs dsgplvm against the other method. Also the per-light-angle means of both methods.
Writes benchmarks/results/ball_regions.{json,md}.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._real_common import RESULTS, direct_render, write_json  # noqa: E402
from benchmarks.diligent_ball import ANGLE_BINS, _load_scene  # noqa: E402

THETA_D_BANDS = ((0, 10), (10, 20), (20, 30), (30, 90))     # MERL θd bins (1° each)
THETA_H_BANDS = ((0, 11), (11, 30), (30, 50), (50, 70), (70, 90))   # MERL θh bins (sqrt-spaced)


def per_light_errors(table, scene_dir):
    """ΔE-log mean over the mask for each reference light -> ((L,) errors, (L,) angles in deg)."""
    from flashbrdf.pipeline.report import image_errors, read_image
    scene, mask, normals, view = _load_scene(scene_dir)
    errors, angles = [], []
    for photo in (p for p in scene["photos"] if p["role"] == "reference"):
        light = np.asarray(photo["light"]["direction"], float)
        image = np.zeros(mask.shape + (3,))
        image[mask] = direct_render(table, np.broadcast_to(light, normals.shape),
                                    np.broadcast_to(view, normals.shape), normals,
                                    np.asarray(photo["light"]["irradiance_rgb"], float))
        errors.append(image_errors(image, read_image(scene_dir / photo["file"]), mask)[1])
        angles.append(np.degrees(np.arccos(np.clip(light @ view, -1, 1))))
    return np.array(errors), np.array(angles)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--against", default="ashikhmin")
    args = ap.parse_args(argv)
    from flashbrdf.brdf.merl import read_merl
    scene_dir = args.work / "scene"
    ours, other = (read_merl(args.work / f"{m}.binary") for m in ("dsgplvm", args.against))
    err_ours, angles = per_light_errors(ours, scene_dir)
    err_other, _ = per_light_errors(other, scene_dir)
    bands = [(lo, hi) for lo, hi in zip(ANGLE_BINS[:-1], ANGLE_BINS[1:])] + [(ANGLE_BINS[-1], 90)]
    result = {"command": "python benchmarks/ball_regions.py " + " ".join(argv or sys.argv[1:]),
              "against": args.against, "dsgplvm": float(err_ours.mean()),
              args.against: float(err_other.mean()), "by_light_angle": [], "swaps": []}
    for lo, hi in bands:
        sel = (angles >= lo) & (angles < hi)
        if sel.any():
            result["by_light_angle"].append({"deg": [lo, hi], "lights": int(sel.sum()),
                                             "dsgplvm": float(err_ours[sel].mean()),
                                             args.against: float(err_other[sel].mean())})
    for axis, name, bands_ in ((1, "theta_d bins", THETA_D_BANDS), (0, "theta_h bins", THETA_H_BANDS)):
        for lo, hi in bands_:
            mixed = ours.copy()
            index = (slice(None),) * axis + (slice(lo, hi),)
            mixed[index] = other[index]
            err = float(per_light_errors(mixed, scene_dir)[0].mean())
            result["swaps"].append({"region": name, "bins": [lo, hi], "delta_e_log": err,
                                    "gain": result["dsgplvm"] - err})
            print(name, lo, hi, round(err, 4), flush=True)
    write_json(RESULTS / "ball_regions.json", result)
    lines = ["# DiLiGenT ball: where dsgplvm loses to " + args.against, "",
             f"Command: `{result['command']}` (after `benchmarks/diligent_ball.py`). ΔE-log mean over "
             f"the 95 reference lights: dsgplvm {result['dsgplvm']:.4f}, {args.against} "
             f"{result[args.against]:.4f}.", "",
             "| light angle from the view (deg) | lights | dsgplvm | " + args.against + " |",
             "|---|---|---|---|"]
    lines += [f"| {b['deg'][0]}–{b['deg'][1]} | {b['lights']} | {b['dsgplvm']:.3f} | "
              f"{b[args.against]:.3f} |" for b in result["by_light_angle"]]
    lines += ["", f"dsgplvm with one region of its table taken from {args.against}:", "",
              "| region | bins | ΔE-log | gain |", "|---|---|---|---|"]
    lines += [f"| {s['region']} | {s['bins'][0]}–{s['bins'][1]} | {s['delta_e_log']:.4f} | "
              f"{s['gain']:+.4f} |" for s in result["swaps"]]
    (RESULTS / "ball_regions.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
