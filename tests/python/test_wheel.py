"""The installable package (docs/install.md): the wheel installs into a fresh venv outside the
repository and everything it needs comes from the wheel, not from the checkout.

Independent references: the checkout's own FMUs (target/fmu, byte for byte and by GUID), the Rust
crate's version in Cargo.toml, the ELF header of the native library against the wheel's platform
tag (read here with the standard library, not with the build hook's logic)."""

from __future__ import annotations

import pathlib
import re
import subprocess
import zipfile

import pytest
from wheel_env import ROOT, clean_env


def rdrive(bin_dir, *args, cwd, timeout=120):
    return subprocess.run(
        [str(bin_dir / "rdrive"), *args],
        cwd=cwd,
        env=clean_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_version_is_the_crates(wheel_venv):
    bin_dir, _, where = wheel_venv
    cargo = (ROOT / "Cargo.toml").read_text()
    version = re.search(r'(?m)^version = "([^"]+)"', cargo).group(1)
    r = rdrive(bin_dir, "--version", cwd=where)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"rdrive {version}"


@pytest.mark.parametrize("model", ["ReciprocatingDrive", "DriveTrain"])
def test_fmu_path_is_the_built_fmu_inside_the_venv(wheel_venv, model):
    bin_dir, _, where = wheel_venv
    r = rdrive(bin_dir, "fmu-path", model, cwd=where)
    assert r.returncode == 0, r.stderr
    path = pathlib.Path(r.stdout.strip())
    assert path.is_file() and where in path.parents  # from the venv, not the checkout
    assert path.read_bytes() == (ROOT / "target" / "fmu" / f"{model}.fmu").read_bytes()


def test_unknown_command_and_model_are_one_line_errors(wheel_venv):
    bin_dir, _, where = wheel_venv
    r = rdrive(bin_dir, "nosuch", cwd=where)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "unknown command 'nosuch'" in r.stderr
    r = rdrive(bin_dir, "fmu-path", "Nope", cwd=where)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "Nope" in r.stderr


def _elf_machine(data: bytes) -> str:
    assert data[:4] == b"\x7fELF", "not an ELF shared object"
    machine = int.from_bytes(data[18:20], "little")
    return {0x3E: "x86_64", 0xB7: "aarch64"}.get(machine, hex(machine))


def test_platform_tag_matches_the_native_code(wheel_venv):
    _, wheel, _ = wheel_venv
    # name-version-python-abi-platform.whl (PEP 427)
    _, _, py, abi, platform = wheel.stem.split("-")
    assert (py, abi) == ("py3", "none")  # loaded with ctypes: no CPython ABI
    with zipfile.ZipFile(wheel) as z:
        lib = z.read("reciprocating_drive/_data/lib/libfmi2_batch.so")
    assert platform == f"linux_{_elf_machine(lib)}"


def test_rdrive_run_outside_the_checkout_equals_the_checkouts_main_job(wheel_venv, tmp_path):
    """The main job from the wheel, in a folder of its own: its summary equals the checkout's run
    of the same command (the same FMU binary, so to the last bit)."""
    import json
    import sys

    bin_dir, _, _ = wheel_venv
    work = tmp_path / "user"
    work.mkdir()
    r = rdrive(bin_dir, "run", "unb600a", cwd=work, timeout=600)
    assert r.returncode == 0, r.stderr
    mine = json.loads((work / "results" / "unb600a.json").read_text())
    ref = tmp_path / "ref"
    r2 = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "simulate.py"), "unb600a", "--out-dir", str(ref)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r2.returncode == 0, r2.stderr
    assert mine == json.loads((ref / "unb600a.json").read_text())
    assert r.stdout == r2.stdout.replace(str(ref), str(work / "results"))


def test_rdrive_twin_replays_the_shipped_sample_from_the_wheel(wheel_venv, tmp_path):
    bin_dir, _, where = wheel_venv
    site = next((where / "venv" / "lib").glob("python3*/site-packages"))
    sample = site / "reciprocating_drive" / "_data" / "twin" / "pump_encoder.csv"
    assert sample.read_bytes() == (ROOT / "data" / "twin" / "pump_encoder.csv").read_bytes()
    r = rdrive(
        bin_dir,
        "twin",
        str(sample),
        "--angle-unit",
        "counts",
        "--counts-per-rev",
        "4096",
        "--out",
        str(tmp_path / "out.csv"),
        cwd=tmp_path,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    lines = (tmp_path / "out.csv").read_text().splitlines()
    assert len(lines) > 1000 and lines[0].startswith("time [s],")


@pytest.mark.parametrize("command", ["run", "twin", "plant", "plc-sim", "sweep", "closed-loop"])
def test_every_command_has_help(wheel_venv, command):
    bin_dir, _, where = wheel_venv
    r = rdrive(bin_dir, command, "--help", cwd=where)
    assert r.returncode == 0 and r.stdout.startswith(f"usage: rdrive {command}"), r.stderr
