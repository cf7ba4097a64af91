"""MERL .binary I/O, the merl-slice command and its bad-input handling."""

import numpy as np
import pytest

from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import MERL_FILE_SIZE, MERL_SCALE, merl_valid_mask, read_merl, write_merl
from flashbrdf.brdf.views import flash_slice, read_slice_csv, slice_coverage, table_2d, table_3d_from_2d
from flashbrdf.cli.main import main


@pytest.fixture(scope="module")
def blue_acrylic(merl_proxy):
    return merl_proxy("blue-acrylic")


def test_read_write_roundtrip_is_bit_exact(blue_acrylic, tmp_path):
    table = read_merl(blue_acrylic)
    assert table.shape == (90, 90, 180, 3)
    out = tmp_path / "copy.binary"
    write_merl(out, table)
    assert out.stat().st_size == MERL_FILE_SIZE == 34_992_012
    # Values go through *scale and /scale: equal to the last bit or one ulp.
    assert out.read_bytes()[:12] == blue_acrylic.read_bytes()[:12]
    np.testing.assert_array_max_ulp(np.nan_to_num(read_merl(out), nan=-1),
                                    np.nan_to_num(table, nan=-1), maxulp=1)
    assert [p.name for p in tmp_path.iterdir()] == ["copy.binary"]  # no temp file left


def test_no_data_matches_the_validity_mask(blue_acrylic):
    table = read_merl(blue_acrylic)
    np.testing.assert_array_equal(np.isfinite(table[..., 0]), merl_valid_mask())


def test_merl_slice_equals_hand_computation(blue_acrylic, tmp_path):
    out = tmp_path / "slice.csv"
    assert main(["merl-slice", str(blue_acrylic), "--out", str(out)]) == 0
    rho, n = read_slice_csv(out)
    raw = np.fromfile(blue_acrylic, dtype="<f8", offset=12).reshape(3, 90, 90, 180)
    for i in range(90):
        for c in range(3):
            values = raw[c, i, 0, :]
            values = values[values >= 0] * MERL_SCALE[c]
            assert n[i] == values.size
            assert abs(rho[i, c] - values.mean()) <= 1e-12 * max(1.0, values.mean())


def test_views_shapes_and_masks(blue_acrylic):
    table = read_merl(blue_acrylic)
    rho, n = flash_slice(table)
    assert rho.shape == (90, 3) and n.shape == (90,) and np.all(np.isfinite(rho))
    t2 = table_2d(table)
    np.testing.assert_allclose(t2[:, 0], rho, rtol=1e-12)
    t3 = table_3d_from_2d(t2)
    np.testing.assert_array_equal(np.isfinite(t3[..., 0]), merl_valid_mask())


def _corrupt(path, tmp_path, kind):
    data = bytearray(path.read_bytes())
    bad = tmp_path / f"{kind}.binary"
    if kind == "truncated":
        bad.write_bytes(bytes(data[: len(data) // 2]))
    elif kind == "header":
        bad.write_bytes(np.array([90, 90, 360], "<i4").tobytes() + bytes(data[12:]))
    elif kind == "nan":
        body = np.frombuffer(bytes(data[12:]), "<f8").copy()
        body[12345] = np.nan
        bad.write_bytes(bytes(data[:12]) + body.tobytes())
    return bad


@pytest.mark.parametrize("kind, words", [("truncated", "bytes"), ("header", "header"),
                                         ("nan", "NaN")])
def test_bad_tables_exit_2_with_one_line_and_no_output(blue_acrylic, tmp_path, capsys, kind,
                                                       words):
    bad = _corrupt(blue_acrylic, tmp_path, kind)
    out = tmp_path / "out" / "slice.csv"
    assert main(["merl-slice", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and words in err[0]
    assert not out.exists()
    with pytest.raises(InputError):
        read_merl(bad)


def test_missing_file_exits_2(tmp_path, capsys):
    assert main(["merl-slice", str(tmp_path / "nope.binary"), "--out",
                 str(tmp_path / "s.csv")]) == 2
    assert "nope.binary" in capsys.readouterr().err


def test_a_bug_inside_a_command_is_not_hidden(tmp_path, monkeypatch):
    # only bad input (InputError) and signals map to exit statuses; anything else is a bug and
    # propagates (the console script then exits 1 with its traceback)
    import flashbrdf.pipeline.run as run_module

    def broken(*args, **kwargs):
        raise NotImplementedError("a bug")

    monkeypatch.setattr(run_module, "run_capture", broken)
    with pytest.raises(NotImplementedError, match="a bug"):
        main(["run", str(tmp_path), "--out", str(tmp_path / "o")])


def test_every_contract_command_has_a_handler():
    """Each command of the contract (INTERFACES.md "Commands") is parsed, with a handler."""
    from flashbrdf.cli.main import build_parser
    parsers = build_parser()._subparsers._group_actions[0].choices
    contract = {"merl-slice", "train", "infer", "extract", "segment", "render", "compare", "run",
                "batch", "export", "evaluate", "import-diligent"}
    assert contract <= set(parsers)
    assert all(callable(parsers[c].get_default("handler")) for c in parsers)


def test_read_merl_bins_equals_read_merl_at_those_bins(blue_acrylic, tmp_path):
    from flashbrdf.brdf.merl import read_merl_bins
    table = read_merl(blue_acrylic)
    rng = np.random.default_rng(0)
    flat = rng.choice(90 * 90 * 180, 5000, replace=False)       # valid and no-data bins alike
    expected = table.reshape(-1, 3)[flat]
    np.testing.assert_array_equal(read_merl_bins(blue_acrylic, flat), expected)  # NaN included
    # float32: one rounding of each value, so within float32's half-ulp (6e-8 relative).
    got32 = read_merl_bins(blue_acrylic, flat, np.float32)
    assert got32.dtype == np.float32
    np.testing.assert_allclose(got32, expected, rtol=1.2e-7)
    # A NaN written into a requested bin is an error naming the file; the input is not modified.
    bad = tmp_path / "bad.binary"
    raw = np.fromfile(blue_acrylic, dtype="<f8", offset=12)
    raw[flat[0]] = np.nan
    bad.write_bytes(blue_acrylic.read_bytes()[:12] + raw.tobytes())
    before = bad.read_bytes()
    with pytest.raises(InputError, match="bad.binary.*NaN/Inf"):
        read_merl_bins(bad, flat)
    assert bad.read_bytes() == before


def test_slice_coverage_by_hand():
    # bins 3..10 filled but 5, and 40: square-root spacing puts bin i's lower edge at 90 (i/90)^2
    # degrees and its centre at 90 ((i + 0.5)/90)^2 (extract's slice.json and the run report
    # both read these numbers).
    filled = np.zeros(90, bool)
    filled[3:11] = True
    filled[5] = False
    filled[40] = True
    cov = slice_coverage(filled)
    assert (cov["bins_filled"], cov["first_bin"], cov["last_bin"], cov["gaps"]) == (8, 3, 40, 30)
    assert len(cov["empty_bins"]) == 82 and cov["empty_bins"][:4] == [0, 1, 2, 5]
    np.testing.assert_allclose(cov["theta_h_deg_range"], [90 * (3 / 90) ** 2, 90 * (41 / 90) ** 2],
                               rtol=1e-12)
    np.testing.assert_allclose(cov["theta_h_deg_filled"],
                               [90 * (3.5 / 90) ** 2, 90 * (40.5 / 90) ** 2], rtol=1e-12)
