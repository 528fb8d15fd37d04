"""Fixtures shared by the Python tests of the FMU.

The FMU is target/fmu/ReciprocatingDrive.fmu, built by scripts/build-fmu.sh (scripts/test.sh builds
it before running pytest). Run by hand without it, the tests are skipped with a message; with CI or
RD_REQUIRE_FMU set (scripts/test.sh sets it) a missing FMU is a failure, never a skip.
RD_FMU=/path/to/X.fmu tests another build.
"""

from __future__ import annotations

import os
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
# The project's Python package (python/reciprocating_drive), ahead of any installed copy.
sys.path.insert(0, str(ROOT / "python"))


def _fmu_path() -> pathlib.Path:
    return pathlib.Path(
        os.environ.get("RD_FMU", ROOT / "target" / "fmu" / "ReciprocatingDrive.fmu")
    )


@pytest.fixture(scope="session")
def fmu_path() -> str:
    p = _fmu_path()
    if not p.is_file():
        msg = f"{p} not found: build it with scripts/build-fmu.sh (scripts/test.sh does)"
        if os.environ.get("CI") or os.environ.get("RD_REQUIRE_FMU"):
            pytest.fail(msg)
        pytest.skip(msg)
    return str(p)


@pytest.fixture(scope="session")
def model_description(fmu_path):
    from fmpy import read_model_description

    return read_model_description(fmu_path)


@pytest.fixture(scope="session")
def vr(model_description) -> dict:
    """Value reference by variable name."""
    return {v.name: v.valueReference for v in model_description.modelVariables}


@pytest.fixture(scope="session")
def unzipdir(fmu_path, tmp_path_factory) -> str:
    from fmpy import extract

    return extract(fmu_path, unzipdir=str(tmp_path_factory.mktemp("fmu")))


@pytest.fixture(scope="session")
def wheel_venv():
    """(bin folder, wheel, folder) of a fresh venv outside the repository with only the project's
    wheel installed (tests/python/wheel_env.py); removed at the end of the session."""
    import shutil
    import tempfile

    from wheel_env import make_wheel_venv, wheel_path

    wheel = wheel_path()
    if wheel is None:
        msg = "target/wheel/*.whl not found: build it with scripts/build-wheel.sh (scripts/test.sh does)"
        if os.environ.get("CI") or os.environ.get("RD_REQUIRE_FMU"):
            pytest.fail(msg)
        pytest.skip(msg)
    where = pathlib.Path(tempfile.mkdtemp(prefix="rdrive-wheel-"))
    os.chmod(where, 0o755)
    try:
        yield make_wheel_venv(where / "venv", wheel), wheel, where
    finally:
        shutil.rmtree(where, ignore_errors=True)


@pytest.fixture(scope="module")
def pg():
    """A temporary PostgreSQL server of Debian's binaries on 127.0.0.1 (tests/python/pg_server.py),
    one per test module."""
    from pg_server import PgServer, pg_bindir

    if pg_bindir() is None:
        pytest.fail(
            "PostgreSQL is not installed: scripts/test.sh installs it (scripts/lib/postgres.sh)"
        )
    with PgServer() as server:
        yield server
