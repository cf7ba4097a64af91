"""Fit Mitsuba 3's `principled` parameters to a MERL table: bounded least squares in log space.

The residual of one bin and channel is sqrt(cos_i cos_o) (ln(rho_model + eps) - ln(rho_table + eps))
over a random subsample of the table's valid bins. The log keeps a highlight of 1000 1/sr from
swamping a diffuse body of 0.1 1/sr, eps = 0.01 1/sr keeps near-black bins (where measurements
are mostly noise) from dominating, and the cosine weight is the irradiance-times-foreshortening
weight of a render, which also plays down MERL's unreliable grazing bins.

Optimiser: scipy's bounded trust-region reflective least squares (`least_squares(method="trf")`),
started from each of a small grid of starts (dielectric / metal, rough / glossy, with and
without clearcoat), the best result kept.
"""

import time

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from flashbrdf.brdf.models.principled import PARAMETER_NAMES, merl_bin_cosines, principled_brdf_angles

FIT_OFFSET = 0.01  # 1/sr, eps of the log residual
OPTIMISER = "scipy.optimize.least_squares (trf, bounded), multi-start"
# Vector layout: base_color r, g, b, then the other parameters in PARAMETER_NAMES order.
_SCALARS = PARAMETER_NAMES[1:]
_LOWER = np.array([0.0, 0.0, 0.0, 0.03] + [0.0] * (len(_SCALARS) - 1))
# specular >= 1e-12 (eta - 1 = 6e-7): Mitsuba drops the main lobe, metallic part and all, where
# eta is 1 in float32 (specular below 1.1e-14), and a fit reaching for a pure metal would stop on
# that edge, where a renderer's float32 rounding decides whether the lobe is there. The dielectric
# Fresnel of eta - 1 = 6e-7 stays below 1e-6 up to θd 89° (1.4e-5 in MERL's last bin, 89.5°):
# a Lambertian is still one.
_LOWER[3 + _SCALARS.index("specular")] = 1e-12
_UPPER = np.ones(3 + len(_SCALARS))


def params_from_vector(x):
    """The parameter dict (Mitsuba names) of a fit vector (11,)."""
    out = {"base_color": [float(v) for v in x[:3]]}
    out.update({name: float(v) for name, v in zip(_SCALARS, x[3:])})
    return out


def vector_from_params(params):
    """The fit vector (11,) of a parameter dict (missing names at Mitsuba's defaults)."""
    from flashbrdf.brdf.models.principled import full_parameters
    p = full_parameters(params)
    return np.concatenate([p["base_color"], [p[name] for name in _SCALARS]])


def sample_valid_bins(table, n_bins, seed=0):
    """Flat indices (<= n_bins,) of random bins where the (90, 90, 180, 3) table is finite."""
    flat = np.flatnonzero(np.all(np.isfinite(np.asarray(table).reshape(-1, 3)), axis=-1))
    if flat.size > n_bins:
        flat = np.sort(np.random.default_rng(seed).choice(flat, n_bins, replace=False))
    return flat


def _starts(base_guess):
    """Candidate start vectors: rough/glossy x dielectric/metal x clearcoat or not."""
    starts = []
    for roughness in (0.15, 0.35, 0.7):
        for metallic in (0.0, 1.0):
            for clearcoat in (0.0, 0.8):
                p = {"base_color": base_guess, "roughness": roughness, "metallic": metallic,
                     "specular": 0.5, "clearcoat": clearcoat, "clearcoat_gloss": 0.5}
                starts.append(vector_from_params(p))
    return starts


def fit_principled(table, n_bins=4000, seed=0, offset=FIT_OFFSET, max_nfev=60):
    """Fit principled parameters to a MERL table (90, 90, 180, 3) in 1/sr (NaN = no data).

    Returns {"params": dict in Mitsuba names, "cost": mean squared weighted log residual,
    "optimiser": str, "seconds": wall seconds, "cpu_seconds": this process's CPU seconds (the
    time on an idle core: the fit is single-threaded), "bins": int, "starts": int,
    "evaluations": int}.
    Raises ValueError when the table has no valid bin.
    """
    start_time, start_cpu = time.perf_counter(), time.process_time()
    table = np.asarray(table, dtype=np.float64)
    flat = sample_valid_bins(table, n_bins, seed)
    if flat.size == 0:
        raise ValueError("the table has no valid bin")
    target = np.maximum(table.reshape(-1, 3)[flat], 0.0)
    cos_i, cos_o, cos_h, cos_d = merl_bin_cosines(flat)
    weight = np.sqrt(np.maximum(cos_i * cos_o, 0.0))[:, None]
    log_target = np.log(target + offset)

    def residual(x):
        model = principled_brdf_angles(cos_i, cos_o, cos_h, cos_d, params_from_vector(x))
        return (weight * (np.log(model + offset) - log_target)).ravel()

    # A diffuse guess for base_color: pi times the median over off-specular bins, per channel.
    off_specular = cos_h < np.cos(np.radians(30.0))
    body = target[off_specular] if off_specular.any() else target
    base_guess = np.clip(np.pi * np.median(body, axis=0), 0.02, 0.98)
    # every start: screening them by their initial residual dropped the metal ones (their base
    # colour is the diffuse guess) and fitted 11 of the 100 MERL (NBRDF proxy) tables 1.4-2.4x
    # worse (a gold paint as a black dielectric, 2D LAB-log 18.2 against 14.2); 3x the time
    screened = _starts(base_guess)
    best, evaluations = None, 0
    for x0 in screened:
        # One BLAS thread: the trust-region SVD of a (12000, 11) Jacobian is 25x slower when
        # OpenBLAS threads fight over 2 shared cores (180 ms against 7 ms per call).
        with threadpool_limits(limits=1, user_api="blas"):
            result = least_squares(residual, x0, bounds=(_LOWER, _UPPER), method="trf",
                                   x_scale=1.0, max_nfev=max_nfev, ftol=1e-7, xtol=1e-7)
        evaluations += result.nfev
        if best is None or result.cost < best.cost:
            best = result
    n_res = best.fun.size
    return {"params": params_from_vector(best.x), "cost": float(2.0 * best.cost / n_res),
            "optimiser": OPTIMISER, "seconds": time.perf_counter() - start_time,
            "cpu_seconds": time.process_time() - start_cpu,
            "bins": int(flat.size), "starts": len(screened), "evaluations": evaluations}
