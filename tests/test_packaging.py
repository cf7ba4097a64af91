"""What `pip install` puts into site-packages: the one import package `flashbrdf`, with every
subpackage of the repository's folders and the default model, and nothing else at the top level."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
STAGE_FOLDERS = ("flashbrdf", "files", "brdf", "capture", "slice_extract", "infer", "render",
                 "pipeline", "experiments", "cli")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                           "--no-build-isolation", "-q", "-w", str(out), str(REPO)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return zipfile.ZipFile(next(out.glob("flashbrdf-*.whl")))


def test_the_wheel_installs_one_top_level_package(wheel):
    tops = {name.split("/")[0] for name in wheel.namelist()}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"flashbrdf"}


def test_every_python_package_of_the_repository_is_in_the_wheel(wheel):
    """A subpackage missing from pyproject's list would import in an editable install and fail
    in a real one."""
    names = set(wheel.namelist())
    for folder in STAGE_FOLDERS:
        for init in (REPO / folder).rglob("__init__.py"):
            relative = init.relative_to(REPO / folder)
            installed = ("flashbrdf" / relative if folder == "flashbrdf" else
                         Path("flashbrdf") / folder / relative).as_posix()
            assert installed in names, f"{init.relative_to(REPO)} is not packaged"


def test_the_wheel_holds_the_default_model_and_the_command(wheel):
    names = set(wheel.namelist())
    assert "flashbrdf/sample_data/models/merl100_1d2d.npz" in names
    entry = next(n for n in names if n.endswith("entry_points.txt"))
    assert "flashbrdf = flashbrdf.cli.main:main" in wheel.read(entry).decode()


def test_no_module_of_the_repository_is_over_500_lines():
    """The house rule (a module is one idea a reader holds at once), over the package, its tests
    and benchmarks alike."""
    long = {}
    for folder in (*STAGE_FOLDERS, "tests", "benchmarks"):
        for module in (REPO / folder).rglob("*.py"):
            count = len(module.read_text(encoding="utf-8").splitlines())
            if count > 500:
                long[str(module.relative_to(REPO))] = count
    assert long == {}
