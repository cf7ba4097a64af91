"""A stand-in with the DSGPLVM interface (GP regression from the 1D view), for adapter tests."""

import numpy as np


class StubDSGPLVM:
    def __init__(self, q=None, beta=50.0, seed=0, **kw):
        self.q, self.beta, self.seed = q, beta, seed

    def fit(self, views, labels=None):
        self.views_ = tuple(views)
        self.y1_ = np.asarray(views["1d"], float)
        self.y2_ = np.asarray(views["2d"], float)
        self.mean2_ = np.nanmean(self.y2_, axis=0)
        d2 = self._dist(self.y1_)
        self.width_ = np.median(d2[d2 > 0]) if np.any(d2 > 0) else 1.0
        return self

    def _dist(self, y):
        y1 = np.nan_to_num(self.y1_)
        ok = np.isfinite(y).all(axis=0) if y.ndim > 1 else np.isfinite(y)
        diff = np.nan_to_num(y)[..., None, ok] - y1[:, ok]
        return (diff ** 2).sum(-1) * (y1.shape[1] / max(ok.sum(), 1))

    def predict_weights(self, slice_features, view="2d"):
        k = np.exp(-self._dist(self.y1_) / self.width_) + 1e-3 * np.eye(len(self.y1_))
        ks = np.exp(-self._dist(np.asarray(slice_features, float)) / self.width_)
        a = np.linalg.solve(k, ks)
        n = len(a)
        return a + (1.0 - a.sum()) / n, float(1.0 - ks @ a)

    def predict(self, slice_features, view="2d"):
        w, var = self.predict_weights(slice_features, view)
        return w @ self.y2_, np.full(self.y2_.shape[1], max(var, 0.0))

    def save(self, path):
        np.savez(path, y1=self.y1_, y2=self.y2_, width=self.width_)

    @classmethod
    def load(cls, path):
        z = np.load(path)
        m = cls()
        m.y1_, m.y2_, m.width_, m.views_ = z["y1"], z["y2"], float(z["width"]), ("1d", "2d")
        return m
