"""Scenes, the CLI and result folders under bad input, concurrency and leftovers.

Every bad input gets one line on stderr and a documented exit code, never a traceback;
two runs on one folder end cleanly; stale temporaries are removed and corrupt payloads
recomputed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scene_texts import TRANS

from continuum_vs_network import _validate
from continuum_vs_network.cli import EXIT, main
from continuum_vs_network.io.atomic import atomic_path, remove_stale_temporaries
from continuum_vs_network.io.lock import FolderBusyError, folder_lock
from continuum_vs_network.report import escape
from continuum_vs_network.scenes.runner import run_scene
from continuum_vs_network.scenes.schema import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[1]

LEARN = """
name = "learn"
description = "tiny learning scene"
seed = 0
kind = "learning"
[network]
builder = "paper"
[task]
kind = "paper"
[learning]
rules = ["gcl"]
trials = 2
steps = 3
"""


def _write(tmp_path: Path, text: str, name: str = "scene.toml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _one_line(err: str) -> str:
    lines = [li for li in err.splitlines() if li.startswith("cvn:")]
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    return lines[0]


# -- scene files --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ('name = "learn"', 'name = "learn\\n"', "name", "plain name"),
        ('name = "learn"', f'name = "{"a" * 300}"', "name", "at most 100"),
        ("seed = 0", "seed = 9223372036854775807", "seed", "seed + trials - 1"),
        ("seed = 0", "seed = -1", "seed", "0..2**63-1"),
        ("trials = 2", "trials = 1000000000", "trials", "too large"),
        ("steps = 3", "steps = 1000000000", "steps", "too large"),
        ("trials = 2", "trials = 2\nsweeps = true\nsweep_points = 1000000000", "sweep_points", ""),
    ],
)
def test_scene_values_are_refused_at_load(tmp_path, old, new, key, words):
    assert old in LEARN
    path = _write(tmp_path, LEARN.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == key and words in str(info.value)


def test_scene_seed_beyond_int64_is_refused(tmp_path):
    path = _write(tmp_path, LEARN.replace("seed = 0", "seed = 1" + "0" * 30))
    with pytest.raises(SceneError, match="seed"):
        load_scene(path)


def test_huge_network_is_refused_naming_n_nodes_and_the_estimate(tmp_path):
    text = LEARN.replace('builder = "paper"', 'builder = "triangular"\nn_nodes = 10000000')
    text = text.replace('kind = "paper"', 'kind = "stern"').replace(
        'rules = ["gcl"]', 'rules = ["gcl"]\nstrain_reference = "initial"'
    )
    with pytest.raises(SceneError) as info:
        load_scene(_write(tmp_path, text))
    err = info.value
    assert (err.table, err.key) == ("network", "n_nodes")
    assert "10000000 is too large" in str(err) and "GiB" in str(err)


def test_resource_limit_follows_the_machine(tmp_path, monkeypatch):
    path = _write(tmp_path, TRANS.replace("sizes = [5, 6]", "sizes = [5, 300]"))
    assert load_scene(path).network.sizes == (5, 300)  # 9e4 nodes: about 1 GB
    monkeypatch.setattr(_validate, "available_memory", lambda: 10**8)
    with pytest.raises(SceneError, match=r"\[network\] sizes"):
        load_scene(path)


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (b'name = "\xff\xfe"\n', "not UTF-8"),
        (("a = " + "[" * 5000 + "]" * 5000 + "\n").encode(), "nested too deeply"),
        (b"name = = 3\n", "not valid TOML"),
    ],
)
def test_unusable_scene_files_exit_2_in_one_line(tmp_path, capsys, content, words):
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == EXIT["usage"]
    assert words in _one_line(capsys.readouterr().err)


def test_unreadable_and_overlong_scene_paths_exit_2(tmp_path, capsys, monkeypatch):
    assert main(["run", "b" * 300 + ".toml", "--out", str(tmp_path), "--quiet"]) == 2
    assert "too long" in _one_line(capsys.readouterr().err)
    assert main(["run", "b" * 300, "--out", str(tmp_path), "--quiet"]) == 2
    _one_line(capsys.readouterr().err)
    assert main(["run", str(tmp_path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "is a folder" in _one_line(capsys.readouterr().err)
    path = _write(tmp_path, TRANS)
    real_open = open

    def denied(file, *args, **kwargs):
        if str(file) == path:
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", denied)
    assert main(["run", path, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "Permission denied" in _one_line(capsys.readouterr().err)


# -- the output folder ------------------------------------------------------------------
def _bad_outs(tmp_path: Path) -> dict[str, Path]:
    afile = tmp_path / "afile"
    afile.write_text("x")
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")
    loop = tmp_path / "loop1"
    loop.symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(loop)
    return {"not a folder": afile, "broken symbolic link": dangling, "loop": loop}


def test_unusable_out_exits_6_in_one_line(tmp_path, capsys):
    scene = _write(tmp_path, TRANS)
    for words, out in _bad_outs(tmp_path).items():
        assert main(["run", scene, "--out", str(out), "--quiet"]) == EXIT["output"] == 6
        assert words in _one_line(capsys.readouterr().err)


def test_read_only_out_exits_6(tmp_path, capsys, monkeypatch):
    import continuum_vs_network.cli as cli

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(kwargs.get("dir")))

    monkeypatch.setattr(cli.tempfile, "mkstemp", refuse)
    scene = _write(tmp_path, TRANS)
    assert main(["run", scene, "--out", str(tmp_path / "ro"), "--quiet"]) == 6
    assert "cannot write there" in _one_line(capsys.readouterr().err)


# -- demo -----------------------------------------------------------------------------------
def test_demo_bad_strain_exits_2_and_failed_method_exits_1(capsys):
    assert main(["demo", "--strain", "-2"]) == EXIT["usage"]
    assert "strain" in _one_line(capsys.readouterr().err)
    assert main(["demo", "--methods", "newton", "lbfgs"]) == 0
    capsys.readouterr()
    # the paper's Adagrad stalls: with a tiny budget it does not converge
    assert main(["demo", "--methods", "newton", "paper", "--paper-seconds", "0.05"]) == 1
    out = capsys.readouterr()
    assert "paper did not converge" in _one_line(out.err)
    assert "newton" in out.out


# -- errors and bugs ----------------------------------------------------------------------
def test_a_bug_shows_its_traceback_and_exits_70(tmp_path, capsys, monkeypatch):
    import continuum_vs_network.cli as cli

    def bug(args):
        raise ZeroDivisionError("a real bug")

    monkeypatch.setitem(cli._COMMANDS, "run", bug)
    assert main(["run", _write(tmp_path, TRANS), "--out", str(tmp_path)]) == EXIT["internal"]
    err = capsys.readouterr().err
    assert "Traceback" in err and "ZeroDivisionError: a real bug" in err and "bug" in err


def test_debug_prints_the_traceback_of_a_user_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("CVN_DEBUG", "0")  # restored after the test; main sets it to 1
    path = _write(tmp_path, TRANS.replace("sizes = [5, 6]", "sizes = [1]"))
    assert main(["--debug", "run", path, "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and "SceneError" in err


# -- the lock -------------------------------------------------------------------------------
def test_second_run_on_a_locked_folder_exits_7_at_once(tmp_path, capsys):
    scene = _write(tmp_path, TRANS)
    with folder_lock(tmp_path / "results" / "trans"):
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        proc = subprocess.run(
            [sys.executable, "-m", "continuum_vs_network", "run", scene, "--out", str(tmp_path)],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
    assert proc.returncode == EXIT["busy"] == 7
    line = _one_line(proc.stderr)
    assert "in use by another cvn run" in line and f"process {os.getpid()}" in line
    assert not (tmp_path / "results" / "trans" / "units").exists()
    # the lock is released: the same run now succeeds (a stale .lock file does not block)
    assert (tmp_path / "results" / "trans" / ".lock").exists()
    assert main(["run", scene, "--out", str(tmp_path), "--quiet"]) == 0


def test_lock_is_reentrant_in_one_process_and_exclusive_across(tmp_path):
    with folder_lock(tmp_path) as a, folder_lock(tmp_path) as b:
        assert a == b
    holder = {"pid": 999_999_999}
    (tmp_path / ".lock").write_text(json.dumps(holder))  # left by a dead process
    with folder_lock(tmp_path):
        assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()
    assert issubclass(FolderBusyError, RuntimeError)


def test_lock_of_a_killed_holder_is_taken_over(tmp_path):
    code = (
        "import sys, time\n"
        "from continuum_vs_network.io.lock import folder_lock\n"
        "with folder_lock(sys.argv[1]):\n"
        "    print('held', flush=True)\n"
        "    time.sleep(60)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-c", code, str(tmp_path)]
    holder = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(FolderBusyError, match=f"process {holder.pid} since"):
            with folder_lock(tmp_path):
                pass
    finally:
        holder.kill()  # SIGKILL: no cleanup runs in the holder
        holder.wait()
    with folder_lock(tmp_path):
        assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()


def test_two_concurrent_runs_on_one_folder_end_cleanly(tmp_path):
    scene = _write(tmp_path, LEARN)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "continuum_vs_network", "run", scene, "--out", str(tmp_path)]
    cmd += ["--quiet", "--no-report"]
    procs = [subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    for p in procs:
        p.stderr.close()
    codes = sorted(rc for rc, _ in results)
    assert codes in ([0, 0], [0, EXIT["busy"]]), results
    for rc, err in results:
        assert "Traceback" not in err
        if rc == EXIT["busy"]:
            assert "in use" in _one_line(err)
    folder = tmp_path / "results" / "learn"
    assert not list(folder.rglob("*.tmp"))
    assert main(["run", scene, "--out", str(tmp_path), "--quiet", "--no-report"]) == 0


# -- leftovers ------------------------------------------------------------------------------
def test_stale_temporaries_are_removed_and_foreign_files_kept(tmp_path):
    scene = load_scene(_write(tmp_path, TRANS))
    folder = tmp_path / "results" / "trans"
    units = folder / "units"
    units.mkdir(parents=True)
    dead = units / ".transmission__n5.npz.999999999.abcd1234.tmp"
    legacy = units / ".transmission__n5.npz.k2j4h5g6.tmp"
    live = units / ".transmission__n5.npz.1.abcd1234.tmp"  # PID 1 is alive
    foreign = units / ".keep_me"
    other_tmp = folder / ".notes.tmp"
    for p in (dead, legacy, live, foreign, other_tmp):
        p.write_text("x")
    run_scene(scene, folder, progress=False)
    assert not dead.exists() and not legacy.exists()
    assert live.exists() and foreign.exists() and other_tmp.exists()
    # without the lock, PID-less names are not touched
    legacy.write_text("x")
    assert remove_stale_temporaries(folder) == 0 and legacy.exists()


def test_atomic_path_names_carry_the_pid_and_leave_nothing_on_failure(tmp_path):
    dest = tmp_path / "a.txt"
    with atomic_path(dest) as tmp:
        assert tmp.name.startswith(f".a.txt.{os.getpid()}.") and tmp.name.endswith(".tmp")
        tmp.write_text("ok")
    assert dest.read_text() == "ok"
    with pytest.raises(RuntimeError), atomic_path(dest) as tmp:
        tmp.write_text("half")
        raise RuntimeError
    assert dest.read_text() == "ok" and [p.name for p in tmp_path.iterdir()] == ["a.txt"]


@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_unit_whose_payload_does_not_load_is_recomputed(tmp_path, damage):
    scene = load_scene(_write(tmp_path, TRANS))
    folder = tmp_path / "results" / "trans"
    first = run_scene(scene, folder, progress=False)
    payload = folder / "units" / "transmission__n6.npz"
    data = payload.read_bytes()
    payload.write_bytes(data[: len(data) // 2] if damage == "truncate" else b"\0" * len(data))
    messages: list[str] = []
    again = run_scene(scene, folder, progress=False, log=messages.append)
    assert any("unreadable payload" in m and "transmission/n6" in m for m in messages)
    assert again.provenance.reused == len(first.units) - 1
    np.testing.assert_allclose(
        again.units["transmission/n6"].arrays["network_strain"],
        first.units["transmission/n6"].arrays["network_strain"],
        rtol=1e-8,
        atol=1e-12,
    )


def test_history_payload_that_does_not_load_is_recomputed(tmp_path):
    scene = load_scene(_write(tmp_path, LEARN))
    folder = tmp_path / "results" / "learn"
    run_scene(scene, folder, progress=False)
    payload = next((folder / "units").glob("train__*trial1.npz"))
    payload.write_bytes(payload.read_bytes()[:100])
    messages: list[str] = []
    again = run_scene(scene, folder, progress=False, log=messages.append)
    assert any("unreadable payload" in m for m in messages)
    assert again.histories["newton/gcl/noise0"].trials == 2


# -- Markdown -----------------------------------------------------------------------------
def test_descriptions_with_pipes_and_html_are_escaped_in_reports(tmp_path):
    text = TRANS.replace("tiny transmission scene", "a | b <script>alert(1)</script> & c")
    assert main(["run", _write(tmp_path, text), "--out", str(tmp_path), "--quiet"]) == 0
    index = (tmp_path / "reports" / "README.md").read_text()
    row = next(li for li in index.splitlines() if "trans/report.md" in li)
    assert "a \\| b &lt;script&gt;alert(1)&lt;/script&gt; &amp; c" in row
    assert row.count(" | ") == 5  # six cells, no extra split
    report = (tmp_path / "reports" / "trans" / "report.md").read_text().splitlines()
    assert "a | b &lt;script&gt;alert(1)&lt;/script&gt; &amp; c" in report
    assert escape.cell("x|y\nz") == "x\\|y z"


def test_oversized_scene_file_and_absurd_worker_count_exit_2(tmp_path, capsys):
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (2 << 20))
    assert main(["run", str(big), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "larger than" in _one_line(capsys.readouterr().err)
    scene = _write(tmp_path, TRANS)
    assert main(["run", scene, "--workers", "100000", "--out", str(tmp_path / "o")]) == 2
    assert "--workers must be in 1.." in _one_line(capsys.readouterr().err)


def test_sweep_grid_too_large_for_memory_is_refused_before_expanding(tmp_path, capsys):
    argv = ["sweep", "paper", "--set", "learning.trials=1..100000", "--set"]
    argv += ["learning.steps=1..1000", "--dry-run", "--out", str(tmp_path), "--quiet"]
    assert main(argv) == EXIT["usage"]
    line = _one_line(capsys.readouterr().err)
    assert "100000000 points" in line and "memory" in line
