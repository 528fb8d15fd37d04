"""A fresh virtual environment outside the repository with only the project's wheel installed (and
its dependencies from the package registry), as a user on another machine gets it: the fixture of
tests/python/test_wheel.py and the cluster tests. The wheel is target/wheel/*.whl, built by
scripts/build-wheel.sh (scripts/test.sh builds it before pytest)."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]


def wheel_path() -> pathlib.Path | None:
    wheels = sorted((ROOT / "target" / "wheel").glob("reciprocating_drive-*.whl"))
    return wheels[-1] if wheels else None


def clean_env(**extra: str) -> dict:
    """The environment of a process that must not see the checkout: no PYTHONPATH, no RD_*."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH" and not k.startswith("RD_")}
    env.update(extra)
    return env


def system_python() -> str:
    """Debian's own python3 (scripts/test.sh installs python3-venv for it): another interpreter than
    the project's venv, and one that another user can run (the venv's base interpreter may live in
    root's home)."""
    return "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys._base_executable


def make_wheel_venv(where: pathlib.Path, wheel: pathlib.Path) -> pathlib.Path:
    """Creates a venv at `where` (world-readable, so another user can run it) with the wheel
    installed; returns its bin/ folder. Bounded: 10 minutes for the install."""
    base = system_python()
    subprocess.run([base, "-m", "venv", str(where)], check=True, timeout=120)
    pip = [str(where / "bin" / "python"), "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(
        [*pip, "install", "--no-input", str(wheel)], check=True, timeout=600, env=clean_env()
    )
    for dirpath, dirnames, filenames in os.walk(where):
        for name in dirnames + filenames:
            p = os.path.join(dirpath, name)
            if not os.path.islink(p):
                mode = os.stat(p).st_mode
                executable = os.path.isdir(p) or mode & 0o100
                os.chmod(p, mode | 0o044 | (0o011 if executable else 0))
    os.chmod(where, 0o755)
    return where / "bin"
