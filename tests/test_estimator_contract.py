"""The scikit-learn estimator contract of every inference method (infer.estimator.InferenceMethod):
get_params round-trips through make_method and sklearn.base.clone, fit never changes a constructor
argument, and fitting on A then on B predicts exactly what a fresh fit on B predicts. Synthetic
Ashikhmin–Premože materials on MERL bin centres (tests/test_infer_baselines.py)."""

import numpy as np
import pytest
from sklearn.base import clone

from flashbrdf.infer import METHODS, InferenceMethod, make_method, method_from_model
from tests.test_infer_uncertainty import materials  # noqa: F401  (the fixture: 9 AP materials)

# every method by name, the DS-GPLVM in both representations, each with a short ADM (the contract
# does not depend on convergence, and two cycles keep a fit under a second)
CASES = [(name, {}) for name in METHODS if name != "dsgplvm"] + [
    ("dsgplvm", {"representation": "absolute", "max_cycles": 2, "feature_space": "rgb"}),
    ("dsgplvm", {"representation": "relative", "max_cycles": 2})]
IDS = [f"{n}-{p.get('representation', '')}".rstrip("-") for n, p in CASES]


def _predict(method, materials, i):
    if method.evaluation_only:
        return method.predict_truth(materials.tables_2d[i])
    return method.predict(materials.slices[i], "2d")[0]


@pytest.mark.parametrize("name,params", CASES, ids=IDS)
def test_params_round_trip_through_make_method_and_clone(name, params):
    method = make_method(name, **params)
    again = make_method(name, **method.get_params())
    assert type(again) is type(method) and again.get_params() == method.get_params()
    copy = clone(method)
    assert type(copy) is type(method) and copy.get_params() == method.get_params()


@pytest.mark.parametrize("name,params", CASES, ids=IDS)
def test_fit_a_then_b_equals_a_fresh_fit_on_b(name, params, materials):
    a, b = materials.subset([0, 1, 2, 3, 4]), materials.subset([2, 3, 4, 5, 6])
    method = make_method(name, **params)
    before = method.get_params()
    method.fit(a)
    assert method.get_params() == before                  # fit stores state in "_" attributes only
    refit = _predict(method.fit(b), materials, 7)
    fresh = _predict(make_method(name, **params).fit(b), materials, 7)
    # same data, same seed, same arithmetic: equal to the last bit (rtol covers BLAS reordering)
    np.testing.assert_allclose(refit, fresh, rtol=1e-12, equal_nan=True)
    # a clone of a fitted method is unfitted with the same hyperparameters
    assert clone(method).get_params() == before and not hasattr(clone(method), "training_")


@pytest.mark.parametrize("representation", ["absolute", "relative"])
def test_from_model_loads_without_refitting(representation, materials):
    train = materials.subset(range(6))
    params = {"representation": representation, "max_cycles": 2}
    fitted = make_method("dsgplvm", **params).fit(train)
    loaded = method_from_model("dsgplvm", fitted.model_, train, **params)
    assert loaded.model_ is fitted.model_ and loaded.get_params() == fitted.get_params()
    np.testing.assert_array_equal(_predict(loaded, materials, 7), _predict(fitted, materials, 7))


def test_abilities_are_declared_on_the_class():
    # callers ask these instead of testing names or hasattr
    flags = {name: (m.evaluation_only, m.closed_form_3d, m.has_uncertainty)
             for name, m in ((n, make_method(n)) for n in METHODS)}
    assert flags == {"dsgplvm": (False, False, True), "pca": (False, False, False),
                     "noll": (False, False, False), "chandraker": (False, True, False),
                     "ashikhmin": (False, True, False), "oracle": (True, False, False)}


def test_ashikhmin_fitted_params_reproduce_the_fit(materials):
    # get_params is the constructor's (r0=None: fit it); fitted_params holds the r0 fit chose
    method = make_method("ashikhmin").fit(materials)
    assert method.get_params() == {"r0": None}
    again = make_method("ashikhmin", **method.fitted_params()).fit(None)
    assert again.r0_ == method.r0_


@pytest.mark.parametrize("name,params", [c for c in CASES if c[0] != "oracle"],
                         ids=[i for i, c in zip(IDS, CASES) if c[0] != "oracle"])
def test_predict_before_fit_is_a_not_fitted_error_except_where_nothing_is_learnt(name, params,
                                                                                 materials):
    from flashbrdf.infer import NotFittedError
    method = make_method(name, **params)
    if not method.needs_fit:    # chandraker: closed form, the same prediction fitted or not
        fitted = make_method(name, **params).fit(materials)
        assert np.array_equal(_predict(method, materials, 0), _predict(fitted, materials, 0),
                              equal_nan=True)
        return
    with pytest.raises(NotFittedError, match="not fitted yet: call fit"):
        method.predict(materials.slices[0], "2d")
    if type(method).novelty is not InferenceMethod.novelty:  # the methods that measure it
        with pytest.raises(NotFittedError):
            method.novelty(materials.slices[0])


def test_predict_slice_is_what_infer_writes_and_predict_takes_the_slice_as_given(materials):
    """A slice with a thin end bin: predict_slice empties it as `flashbrdf infer` does (its
    prediction ignores the bin's value), predict uses it (a bin 10x off moves the table)."""
    from flashbrdf.infer import predict_slice
    method = make_method("pca").fit(materials.subset([1, 2, 3, 4, 5, 6, 7, 8]))
    rho = np.array(materials.slices[0], dtype=float)
    n = np.full(90, 500)
    n[87:] = 1                     # a sparse tail of three bins
    off = rho.copy()
    off[87:] *= 10.0
    tail_dropped = predict_slice(method, off, n, "2d")
    assert tail_dropped.ignored == [87, 88, 89]
    assert np.array_equal(tail_dropped.table, predict_slice(method, rho, n, "2d").table,
                          equal_nan=True)
    assert not np.allclose(method.predict(off, "2d")[0], tail_dropped.table, equal_nan=True)
