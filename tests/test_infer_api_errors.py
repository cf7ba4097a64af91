"""Errors of the inference API named as the caller's, not the model file's."""

import pytest


def test_an_unknown_method_name_is_the_callers_not_the_model_files(tmp_path):
    """load_method(model, "PCA") said the (sound) model was damaged; the name is checked first,
    before the file is read: a path that does not exist gives the same error."""
    from flashbrdf.files.errors import InputError
    from flashbrdf.infer import load_method
    with pytest.raises(InputError) as err:
        load_method(tmp_path / "no_such_model.npz", "PCA")
    assert err.value.where == "method" and "unknown method 'PCA'" in str(err.value)
    assert "damaged" not in str(err.value)


def test_a_callers_bad_override_is_named_as_the_callers_not_the_files():
    """load_method(model, "dsgplvm", calibration=-1.0) said the shipped model was damaged."""
    from flashbrdf.files.errors import InputError
    from flashbrdf.infer import load_method
    from flashbrdf.pipeline.options import DEFAULT_MODEL
    with pytest.raises(InputError) as err:
        load_method(DEFAULT_MODEL, "dsgplvm", calibration=-1.0)
    assert err.value.where == "dsgplvm override" and "damaged" not in str(err.value)
    assert "'calibration'] is -1.0, expected a positive number" in str(err.value)
