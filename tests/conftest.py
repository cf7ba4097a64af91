"""Shared test fixtures: MERL (NBRDF proxy) tables made on demand, and the shared/ folder."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# The property tests draw the same cases on every run, so main stays green at every commit;
# HYPOTHESIS_PROFILE=explore draws new ones (and keeps what fails in .hypothesis/) when hunting.
settings.register_profile("ci", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

SHARED = Path(os.environ.get("FLASHBRDF_SHARED",
                             Path(__file__).resolve().parents[2] / "shared"))
MERL_PROXY_TOOL = SHARED / "tools" / "merl_proxy.py"


def shared_path(*parts):
    """A path under ../shared, or skip the test with the reason when it is absent."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is absent (../shared beside the checkout is needed)")
    return path


@pytest.fixture(scope="session")
def merl_proxy(tmp_path_factory):
    """Function name -> path of that MERL (NBRDF proxy) `.binary` table, generated once a session
    into a temp folder with ../shared/tools/merl_proxy.py (about 0.5 s a material)."""
    if not MERL_PROXY_TOOL.exists():
        pytest.skip(f"{MERL_PROXY_TOOL} is absent (../shared beside the checkout is needed)")
    folder = tmp_path_factory.mktemp("merl_proxy")

    def make(*names):
        missing = [n for n in names if not (folder / f"{n}.binary").exists()]
        if missing:
            subprocess.run([sys.executable, str(MERL_PROXY_TOOL), "--out", str(folder),
                            "--materials", *missing], check=True, capture_output=True)
        paths = [folder / f"{n}.binary" for n in names]
        return paths[0] if len(paths) == 1 else paths

    return make
