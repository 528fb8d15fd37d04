"""scripts/lib/ensure-build-deps.sh finds the libclang that bindgen (clang-sys) can load, and only
that one, against fake directory trees (issue: a machine with only libclang-cpp.so.14 made the old
`libclang*` glob believe libclang was there, and the build of fmi-sys failed).

The expectation is clang-sys's own rule, written independently here: a usable library is named
libclang.so, libclang-N.so, libclang.so.N or libclang-N.so.N (N a version), never libclang-cpp.
"""

from __future__ import annotations

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "lib" / "ensure-build-deps.sh"


def run(tree: pathlib.Path, install: str = "echo INSTALLER-CALLED >&2") -> tuple[int, str, str]:
    env = {k: v for k, v in os.environ.items() if k != "LIBCLANG_PATH"}
    env.update(
        RD_LIBCLANG_DIRS=f"{tree}/usr/lib/llvm-*/lib:{tree}/usr/lib*:{tree}/usr/lib/*",
        RD_LIBCLANG_INSTALL=install,
    )
    p = subprocess.run(
        [
            "bash",
            "-c",
            f'source "{SCRIPT}"; ensure_libclang && echo "LIBCLANG_PATH=$LIBCLANG_PATH"',
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,
    )
    return p.returncode, p.stdout, p.stderr


def touch(tree: pathlib.Path, rel: str) -> pathlib.Path:
    p = tree / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.touch()
    return p


def test_only_libclang_cpp_is_not_libclang(tmp_path):
    touch(tmp_path, "usr/lib/llvm-14/lib/libclang-cpp.so.14")
    touch(tmp_path, "usr/lib/x86_64-linux-gnu/libclang-cpp.so.14")
    rc, out, err = run(tmp_path)
    assert "INSTALLER-CALLED" in err, "libclang-cpp must not count as libclang: install expected"
    assert rc != 0 and "still missing" in err  # the fake installer installed nothing


@pytest.mark.parametrize(
    "name", ["libclang-14.so.1", "libclang.so.1", "libclang-14.so", "libclang.so"]
)
def test_versioned_libclang_outside_the_default_path_is_found(tmp_path, name):
    touch(tmp_path, "usr/lib/llvm-14/lib/libclang-cpp.so.14")
    lib = touch(tmp_path, f"usr/lib/llvm-14/lib/{name}")
    rc, out, err = run(tmp_path)
    assert rc == 0, err
    assert "INSTALLER-CALLED" not in err
    assert f"LIBCLANG_PATH={lib.parent}" in out


def test_none_installs_then_finds(tmp_path):
    # The "installer" puts a libclang where apt's libclang-dev would (a versioned file).
    target = tmp_path / "usr/lib/llvm-16/lib"
    rc, out, err = run(
        tmp_path,
        install=f'echo INSTALLER-CALLED >&2; mkdir -p "{target}"; touch "{target}/libclang-16.so.16"',
    )
    assert "INSTALLER-CALLED" in err
    assert rc == 0, err
    assert f"LIBCLANG_PATH={target}" in out


def test_this_machine_has_a_usable_libclang():
    """After the scripts ran (scripts/test.sh runs ensure_build_deps first) the real search finds
    a library with a usable name that exists."""
    env = {k: v for k, v in os.environ.items() if k != "LIBCLANG_PATH"}
    p = subprocess.run(
        ["bash", "-c", f'source "{SCRIPT}"; find_libclang'],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert p.returncode == 0, p.stderr
    path = pathlib.Path(p.stdout.strip())
    assert path.exists() and "libclang-cpp" not in path.name
