"""The installed package on its own (docs/install.md "Examples"): in a fresh venv outside the
repository with only the wheel (tests/python/wheel_env.py), `rdrive examples DIR` makes a folder in
which the README's and the docs' `.venv/bin/rdrive` commands run as written; nothing is written
inside the installation; help texts and messages name `rdrive` commands; a missing optional
importer is named with the extra that installs it.

Independent references: the commands are read from README.md and docs/*.md themselves (not a
copy), the copied files are compared byte for byte with the repository's, and the installation is
checked by listing its files before and after.
"""

from __future__ import annotations

import os
import pathlib
import re
import shlex
import subprocess

import pytest
from wheel_env import ROOT, clean_env

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Commands that need what a single test cannot give: a cluster, the demo's OPC UA server and
#: page (tested in test_page_plant.py from the checkout), or a PLC already playing
#: (examples/twin/opcua-plc.toml; tested in test_plant_stop_cycle.py from the checkout).
NOT_HERE = re.compile(r"--scheduler|--demo|opcua-plc\.toml")


def doc_commands() -> list[tuple[str, str]]:
    """(page:line, command) of every `.venv/bin/rdrive` command in a ```sh block of the pages,
    continuation lines joined, comments dropped."""
    out = []
    for page in PAGES:
        lines = page.read_text().split("\n")
        inside = False
        cur, at = "", 0
        for i, line in enumerate(lines, 1):
            if line.startswith("```"):
                inside = line.strip() == "```sh"
                continue
            if not inside:
                continue
            if cur:
                cur += " " + line.strip()
            elif line.startswith(".venv/bin/rdrive"):
                cur, at = line.strip(), i
            else:
                continue
            if cur.endswith("\\"):
                cur = cur[:-1].rstrip()
                continue
            cmd = cur.split(" #")[0].strip()
            out.append((f"{page.relative_to(ROOT)}:{at}", cmd))
            cur = ""
    return out


COMMANDS = doc_commands()


def installation_files(where: pathlib.Path) -> set[str]:
    site = next((where / "venv" / "lib").glob("python3*/site-packages"))
    pkg = site / "reciprocating_drive"
    return {
        str(p.relative_to(pkg))
        for p in pkg.rglob("*")
        if "__pycache__" not in p.parts and not p.name.endswith(".pyc")
    }


def sh(bin_dir, command: str, cwd, timeout=600) -> subprocess.CompletedProcess:
    env = clean_env(PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", MPLBACKEND="Agg")
    return subprocess.run(
        ["bash", "-c", command],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


@pytest.fixture(scope="module")
def examples(wheel_venv, tmp_path_factory):
    bin_dir, _, where = wheel_venv
    work = tmp_path_factory.mktemp("user")
    r = sh(bin_dir, "rdrive examples ex", cwd=work)
    assert r.returncode == 0, r.stderr
    return bin_dir, where, work / "ex"


def test_examples_are_the_repositorys_files(examples):
    _, _, ex = examples
    expected = ["data/twin/pump_encoder.csv"]
    expected += [f"examples/twin/{p.name}" for p in (ROOT / "examples" / "twin").glob("*.toml")]
    expected += [f"studies/{p.name}" for p in (ROOT / "studies").glob("*.toml")]
    got = sorted(str(p.relative_to(ex)) for p in ex.rglob("*") if p.is_file())
    assert got == sorted(expected)
    for rel in expected:
        assert (ex / rel).read_bytes() == (ROOT / rel).read_bytes(), rel


def test_examples_does_not_overwrite(examples):
    bin_dir, _, ex = examples
    r = sh(bin_dir, f"rdrive examples {shlex.quote(str(ex))}", cwd=ex.parent)
    assert r.returncode == 2
    assert r.stderr.startswith("rdrive examples: ") and "--force" in r.stderr
    assert len(r.stderr.strip().split("\n")) == 1


def test_the_docs_commands_are_found():
    # The README's twin, sweep and closed-loop commands at least.
    text = " ".join(c for _, c in COMMANDS)
    for part in ("rdrive twin data/twin", "rdrive sweep studies/", "rdrive closed-loop"):
        assert part in text, part


@pytest.mark.parametrize("where, command", COMMANDS, ids=[w for w, _ in COMMANDS])
def test_doc_command_runs_in_the_examples_folder(examples, where, command):
    bin_dir, venv_root, ex = examples
    if NOT_HERE.search(command):
        pytest.skip(f"{command}: needs a cluster, the demo's server or a playing PLC")
    before = installation_files(venv_root)
    cmd = command.replace(".venv/bin/rdrive", "rdrive", 1)
    r = sh(bin_dir, cmd, cwd=ex)
    if re.fullmatch(r"rdrive closed-loop(\s+--importer libcosim)?", cmd.split(" #")[0].strip()):
        # The wheel is installed without the libcosim extra: one line naming it, exit code 2.
        assert r.returncode == 2, (r.stdout, r.stderr)
        assert r.stderr.strip() == (
            "rdrive closed-loop: --importer libcosim (the default) needs libcosimpy, which is not "
            "installed: pip install 'reciprocating-drive[libcosim]', or use --importer fmpy"
        )
    else:
        assert r.returncode == 0, f"{where}: {cmd}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
        assert "Traceback" not in r.stderr
    assert installation_files(venv_root) == before, "written inside the installation"


def test_a_shipped_configuration_never_writes_into_the_installation(wheel_venv, tmp_path):
    bin_dir, _, where = wheel_venv
    site = next((where / "venv" / "lib").glob("python3*/site-packages"))
    shipped = site / "reciprocating_drive" / "_data" / "examples" / "replay-sqlite.toml"
    before = installation_files(where)
    r = sh(bin_dir, f"rdrive plant --config {shlex.quote(str(shipped))}", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("rdrive plant: ") or "rdrive examples DIR" in r.stderr, r.stderr
    assert "inside the installed package" in r.stderr and "rdrive examples DIR" in r.stderr
    assert installation_files(where) == before


@pytest.mark.parametrize("command", ["run", "twin", "plant", "plc-sim", "sweep", "closed-loop"])
def test_help_names_rdrive_commands(wheel_venv, command):
    bin_dir, _, where = wheel_venv
    r = sh(bin_dir, f"rdrive {command} --help", cwd=where)
    assert r.returncode == 0, r.stderr
    assert ".venv/bin/python" not in r.stdout and "scripts/" not in r.stdout, r.stdout


def test_messages_name_the_rdrive_command(examples, tmp_path):
    bin_dir, _, _ = examples
    bad = tmp_path / "bad.csv"
    bad.write_text("time,crank_angle\n0,0\nx,1\n")
    r = sh(bin_dir, f"rdrive twin {bad} --out {tmp_path / 'o.csv'}", cwd=tmp_path)
    assert r.returncode == 1
    assert r.stderr.startswith(f"rdrive twin: {bad}: line 3: time = 'x' is not a number"), r.stderr


def test_install_md_examples_command(wheel_venv, tmp_path):
    """docs/install.md "Examples": its one command, as written, from an empty folder."""
    bin_dir, where, _ = wheel_venv[0], wheel_venv[2], None
    text = (ROOT / "docs" / "install.md").read_text()
    (command,) = [line for line in text.split("\n") if line.startswith("rdrive examples ")]
    before = installation_files(where)
    r = sh(bin_dir, command, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "pump-examples" / "results" / "twin" / "outputs.csv").is_file()
    assert (tmp_path / "pump-examples" / "results" / "twin" / "sample-replay.sqlite").is_file()
    assert installation_files(where) == before
