"""Shared fixtures: the repository's simulated records and the CLI binary to compare with."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "fixtures"
TRAIN = [FIXTURES / "kresling-30db-train-1.csv", FIXTURES / "kresling-30db-train-2.csv"]
TEST = FIXTURES / "kresling-30db-test.csv"
LIBRARY = "x^1..7, x', xb_acc"

# The paper's Table 1 model of the Kresling cell (its surrogate truth), as a tfs-model/1 file.
PAPER_MODEL = """{"format":"tfs-model/1","dofs":["x"],"inputs":["xb_acc"],
"equations":[{"dof":"x","terms":[{"term":"x'","coef":-2.0},{"term":"x^5","coef":-12.12},
{"term":"x^6","coef":18.03},{"term":"x^7","coef":-6.56},{"term":"xb_acc","coef":-1.0}]}],
"method":"paper"}"""


def cli_path():
    """The `tfs` binary of this checkout: $TFS_CLI, else target/{debug,release}/tfs."""
    env = os.environ.get("TFS_CLI")
    if env:
        return env
    for profile in ("debug", "release"):
        p = ROOT / "target" / profile / "tfs"
        if p.exists():
            return str(p)
    return shutil.which("tfs")


@pytest.fixture(scope="session")
def cli():
    path = cli_path()
    if path is None:
        pytest.fail("no tfs binary: build it with `cargo build -p tfs` or set TFS_CLI")
    return path
