"""Persistence of a fitted DS-GPLVM as one .npz (no pickles).

Always stored: configuration, latent X, labels, per view ln θ, γ, λ, A, Λ, column mask, scale, D, and
the source (1D) view's training features. A view's training features (needed by predict; predict_weights
needs none) are stored for the views in store_views (default: those the model kept in memory).
"""

import json

import numpy as np

from flashbrdf.files.atomic import atomic_path
from flashbrdf.files.errors import InputError

from .viewdata import ViewData

FORMAT = "flashbrdf-dsgplvm-1"


def save_model(model, path, store_views=None):
    """Write `model` to `path` (.npz) atomically; store_views: views whose training data to keep."""
    if store_views is None:
        store_views = [v for v in model.view_names_ if model.view_data_[v].data is not None]
    store_views = set(store_views) | {model.source_view}
    meta = {"format": FORMAT, "views": model.view_names_, "stored": sorted(store_views),
            "config": model.get_params(),
            "objective_history": model.objective_history_, "mu": model.mu_,
            "gamma": model.gamma_, "lambda": model.lambda_, "n_cycles": model.n_cycles_,
            "fit_time": getattr(model, "fit_time_", None)}
    arrays = {"meta": np.array(json.dumps(meta)), "latent": model.latent_,
              "labels": model.labels_}
    for v in model.view_names_:
        data = model.view_data_[v]
        arrays[f"{v}_log_theta"] = model.log_theta_[v]
        arrays[f"{v}_A"] = model.backmap_weights_[v]
        arrays[f"{v}_multipliers"] = model.multipliers_[v]
        arrays[f"{v}_keep"] = data.keep
        arrays[f"{v}_gram"] = data.gram
        arrays[f"{v}_scale_dims"] = np.array([data.scale, data.n_dims], dtype=float)
        if v in store_views:
            if data.data is None:
                raise ValueError(f"view {v!r} training data is not in memory; fit with store_views")
            arrays[f"{v}_mean"] = data.mean
            arrays[f"{v}_data"] = data.data
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)


def load_model(cls, path):
    """Read a model written by save_model; InputError if the file is not one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(str(arrays["meta"]))
    except (OSError, ValueError, KeyError) as err:
        raise InputError(path, f"cannot read DS-GPLVM model ({err})") from None
    if meta.get("format") != FORMAT:
        raise InputError(path, "not a flashbrdf DS-GPLVM model")
    cfg = meta["config"]
    cfg["views"] = tuple(cfg["views"])
    model = cls(**cfg)
    names = meta["views"]
    model.view_names_ = names
    model.latent_ = arrays["latent"]
    model.q_ = model.latent_.shape[1]
    model.labels_ = arrays["labels"]
    model.log_theta_ = {v: arrays[f"{v}_log_theta"] for v in names}
    model.backmap_weights_ = {v: arrays[f"{v}_A"] for v in names}
    model.multipliers_ = {v: arrays[f"{v}_multipliers"] for v in names}
    model.gamma_ = {v: float(meta["gamma"][v]) for v in names}
    model.lambda_ = {v: float(meta["lambda"][v]) for v in names}
    model.mu_ = meta["mu"]
    model.objective_history_ = meta["objective_history"]
    model.n_cycles_ = meta["n_cycles"]
    model.fit_time_ = meta["fit_time"]
    model.view_data_ = {}
    for v in names:
        scale, dims = arrays[f"{v}_scale_dims"]
        model.view_data_[v] = ViewData(keep=arrays[f"{v}_keep"], mean=arrays.get(f"{v}_mean"),
                                       scale=float(scale), gram=arrays[f"{v}_gram"],
                                       n_dims=int(dims), data=arrays.get(f"{v}_data"))
    model._build_posteriors()
    return model
