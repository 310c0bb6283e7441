"""The ``cvn`` command: listing, exit codes that say what failed, export."""

from __future__ import annotations

import json
import subprocess
import sys

from scene_texts import TRANS

from continuum_vs_network.cli import EXIT, main
from continuum_vs_network.scenes.schema import builtin_names, load_scene

EXPLODE = """
name = "explode"
description = "an explicit step far above the stability limit"
kind = "relaxation"
[network]
builder = "triangular"
sizes = [4]
[dynamics]
scheme = "explicit"
steps_per_tau = 2
"""


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_scenes_lists_every_builtin_with_its_description(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name in builtin_names():
        scene = load_scene(name)
        line = next(li for li in out.splitlines() if li.startswith(name + " "))
        assert scene.description in line and scene.kind in line
        assert ("yes" if scene.report.default else "no") in line.split()
    assert main(["scenes", "--keys"]) == 0
    assert "[learning]" in capsys.readouterr().out


def test_bad_scene_exits_2_naming_file_table_and_key(tmp_path, capsys):
    path = _write(tmp_path, TRANS.replace('kind = "source"', 'kind = "source"\nstrian = 0.1'))
    assert main(["run", path, "--out", str(tmp_path), "--quiet"]) == EXIT["usage"] == 2
    err = capsys.readouterr().err
    assert path in err and "[task]" in err and "strian" in err and "unknown key" in err
    assert main(["run", str(tmp_path / "none.toml"), "--out", str(tmp_path)]) == 2
    assert main(["report", "no_such_builtin", "--out", str(tmp_path)]) == 2
    assert main(["run", path, "--workers", "0"]) == 2
    assert not (tmp_path / "results").exists()


def test_failed_computation_exits_3_and_says_where(tmp_path, capsys):
    path = _write(tmp_path, EXPLODE)
    assert main(["run", path, "--out", str(tmp_path), "--quiet"]) == EXIT["run"] == 3
    err = capsys.readouterr().err
    assert "explode" in err and "relaxation/n4" in err and "rerun to resume" in err


def test_report_and_export_failures_have_their_own_codes(tmp_path, monkeypatch, capsys):
    path = _write(tmp_path, TRANS)
    import continuum_vs_network.report.writer as writer
    import continuum_vs_network.scenes.meshes as meshes

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(writer, "write_report", boom)
    assert main(["run", path, "--out", str(tmp_path), "--quiet"]) == EXIT["report"] == 4
    assert "writing the report failed: OSError: disk full" in capsys.readouterr().err
    monkeypatch.setattr(meshes, "export_meshes", boom)
    assert main(["export", path, "--out", str(tmp_path), "--quiet"]) == EXIT["export"] == 5
    assert "writing meshes failed" in capsys.readouterr().err


def test_export_writes_meshes_of_a_scene_without_export_table(tmp_path):
    path = _write(tmp_path, TRANS)
    assert main(["run", path, "--out", str(tmp_path), "--quiet"]) == 0
    assert not (tmp_path / "meshes").exists()
    assert main(["export", path, "--out", str(tmp_path), "--quiet"]) == 0
    assert [p.name for p in (tmp_path / "meshes" / "trans").iterdir()] == ["network_n6.vtu"]
    index = (tmp_path / "reports" / "README.md").read_text()
    assert "[trans](trans/report.md)" in index


def test_report_runs_named_scenes_and_writes_the_index(tmp_path):
    a = _write(tmp_path, TRANS, "a.toml")
    b = _write(tmp_path, TRANS.replace('name = "trans"', 'name = "trans2"'), "b.toml")
    assert main(["report", a, b, "--out", str(tmp_path), "--quiet"]) == 0
    index = (tmp_path / "reports" / "README.md").read_text()
    assert "trans/report.md" in index and "trans2/report.md" in index
    # a failing scene does not stop the others; the exit code names the first failure
    c = _write(tmp_path, EXPLODE, "c.toml")
    assert main(["report", c, a, "--out", str(tmp_path), "--quiet"]) == 3


def test_every_subcommand_has_a_handler():
    import continuum_vs_network.cli as cli

    (sub,) = cli.build_parser()._subparsers._group_actions
    assert set(sub.choices) == set(cli._COMMANDS)


def test_the_command_line_imports_no_heavy_dependency():
    code = (
        "import json, sys\n"
        "from continuum_vs_network.cli import build_parser\n"
        "build_parser().parse_args(['run', 'x.toml'])\n"
        "heavy = ('dask', 'distributed', 'pandas', 'pyarrow', 'pyvista', 'vtk', 'matplotlib',\n"
        "         'skfem', 'meshio', 'torch')\n"
        "print(json.dumps(sorted(m for m in heavy if m in sys.modules)))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout) == []
