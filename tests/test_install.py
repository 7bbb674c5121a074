"""Installs the way users install: a wheel built from this tree carries the whole package and
its shipped data (scenes, assets, the viewer's web files), and the scenes round-trip through
``bulletnet scene``. (.ci/run also installs that wheel into a fresh environment and runs
scenes from a temporary folder.)"""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
from test_recording_cli import cli

import bulletnet as bn
import bulletnet.model.scenario
from bulletnet.common.resources import FOLDERS, data_dir

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                           str(out), str(ROOT)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    (path,) = out.glob("bulletnet-*.whl")
    return path


def test_wheel_holds_every_module_and_every_data_file(wheel):
    # Reference: the source tree. Every module of the package and every file of the data
    # folders is in the wheel, the data inside the package where bulletnet.common.resources looks.
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {p.relative_to(ROOT).as_posix() for p in (ROOT / "bulletnet").rglob("*.py")}
    for folder in FOLDERS:
        expected |= {f"bulletnet/{folder}/{p.relative_to(ROOT / folder).as_posix()}"
                     for p in (ROOT / folder).rglob("*")
                     if p.is_file() and "__pycache__" not in p.parts}
    assert sorted(expected - names) == []


def test_data_folders_are_found_in_the_source_tree():
    # Reference: this checkout's top-level folders (an editable install reads them in place).
    for folder in FOLDERS:
        assert data_dir(folder) == ROOT / folder


def test_scenes_lists_every_shipped_scene_with_its_description():
    proc = cli("scenes")
    assert proc.returncode == 0, proc.stderr
    for name in bn.model.scenario.scene_names():
        line = next(x for x in proc.stdout.splitlines() if x.startswith(name + " "))
        assert bn.load_scenario(name).scene.description in line


@pytest.mark.parametrize("full", [False, True])
def test_scene_prints_toml_that_reads_back_as_the_same_scene(tmp_path, full):
    # Reference: the shipped scene itself. Its printed TOML, saved in another folder (the
    # file's `base` then names the shipped scene), loads to an equal scene.
    for name in bn.model.scenario.scene_names():
        proc = cli("scene", name, *(["--full"] if full else []))
        assert proc.returncode == 0, proc.stderr
        tomllib.loads(proc.stdout)
        mine = tmp_path / f"mine_{name}.toml"
        mine.write_text(proc.stdout)
        assert bn.load_scenario(str(mine)) == bn.load_scenario(name)


def test_scene_refuses_a_study_file_in_one_line():
    proc = cli("scene", "study_ishigami")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "a study file, not a scene" in proc.stderr
