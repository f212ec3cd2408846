"""Never lose a file, never crash: the output policy, odd inputs, bounded work, outliers.

Every refusal is a located ``LB…`` diagnostic with exit code 2, no traceback, and the
user's files are byte-for-byte as they were.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.files.outputs import LEDGER_NAME

REPO = Path(__file__).resolve().parents[2]


def _digest(root: Path) -> dict:
    """Every file under ``root`` (or ``root`` itself) with its sha256."""
    if root.is_file():
        return {root.name: hashlib.sha256(root.read_bytes()).hexdigest()}
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _no_traceback(err: str) -> None:
    assert "Traceback" not in err


# --------------------------------------------------------------------------- a measurement set by hand

#: the minimal booth: one isotropic 1000 cd point at (0, 0, 700) mm, no effects: E = I·cos θ/d² exactly
I_CD, LAMP_MM = 1000.0, np.array([0.0, 0.0, 700.0])


def closed_form_lux(p_mm) -> np.ndarray:
    d = LAMP_MM - np.asarray(p_mm, float)
    r = np.linalg.norm(d, axis=-1) / 1000.0
    return I_CD * (d[..., 2] / 1000.0 / r) / r ** 2


@pytest.fixture
def meas_set(minimal_booth, tmp_path):
    """A measurement set of the minimal booth whose readings are the closed form × (1 + 0.5 % noise)."""
    d = tmp_path / "m"
    d.mkdir()
    rng = np.random.default_rng(3)
    pts = np.array([[x, y, 0.0] for x in np.linspace(-400, 400, 7) for y in np.linspace(-250, 250, 5)])
    lux = closed_form_lux(pts) * (1 + 0.005 * rng.standard_normal(len(pts)))
    (d / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{p[0]:g},{p[1]:g},{e:.3f}\n" for p, e in zip(pts, lux)))
    (d / "meas.yaml").write_text(
        "version: 1\nkind: measurement_set\nname: hand-made\n"
        f"booth: {os.path.relpath(minimal_booth, d)}\nlighting: A\n"
        "instrument: {illuminance_meter: test meter, repeatability_percent: 0.5}\n"
        "known_output_groups: [bulb]\n"
        "illuminance:\n  - path: grid.csv\n")
    return d / "meas.yaml"


# --------------------------------------------------------------------------- build --out


@pytest.mark.parametrize("target", ["user_folder", "booth_folder", "regular_file", "cwd", "under_a_file",
                                    "proc", "with_user_file"])
def test_build_out_never_replaces_what_lbscene_did_not_make(target, minimal_booth, tmp_path, run_cli):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("my notes")
    afile = tmp_path / "afile.txt"
    afile.write_text("precious")
    built = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", built)[0] == 0
    (built / "mine.txt").write_text("mine") if target == "with_user_file" else None
    out, code_want, message = {
        "user_folder": (user, "LB611", "folder exists and is not an lbscene output"),
        "booth_folder": (minimal_booth, "LB612", "output folder would replace or hold one of this run's inputs"),
        "regular_file": (afile, "LB610", "exists and is not a folder"),
        "cwd": (Path("."), "LB610", "the current folder cannot be an output folder"),
        "under_a_file": (afile / "sub", "LB610", "cannot write here: a parent of this path is a file"),
        "proc": (Path("/proc/lbscene-test"), "LB610", "cannot write in the folder '/proc'"),
        "with_user_file": (built, "LB611", "folder holds files lbscene did not write"),
    }[target]
    before = {p: _digest(p) for p in (user, afile, minimal_booth, built)}
    code, stdout, err = run_cli("build", minimal_booth, "--out", out,
                                cwd=user if target == "cwd" else tmp_path)
    assert code == 2, err
    _no_traceback(err)
    assert f"error {code_want}: --out: {message}" in err
    assert {p: _digest(p) for p in (user, afile, minimal_booth, built)} == before


def test_a_build_lbscene_made_is_replaced_and_leftovers_of_a_killed_run_removed(minimal_booth, tmp_path,
                                                                              run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    first = json.loads((out / "manifest.json").read_text())["ir_hash"]
    # what a build killed with SIGKILL leaves: its temporary folder, named with its (dead) pid
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    stale = tmp_path / f".b.lbtmp-{dead}-deadbeef"
    stale.mkdir()
    (stale / "scene.usda").write_text("half")
    (minimal_booth / "booth.yaml").write_text(
        (minimal_booth / "booth.yaml").read_text().replace("value_cd: 1000", "value_cd: 1500"))
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    assert json.loads((out / "manifest.json").read_text())["ir_hash"] != first     # rebuilt
    assert not stale.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".b.")) == []


def test_an_empty_folder_is_an_acceptable_build_folder(minimal_booth, tmp_path, run_cli):
    (tmp_path / "empty").mkdir()
    assert run_cli("build", minimal_booth, "--out", tmp_path / "empty")[0] == 0
    assert (tmp_path / "empty" / "manifest.json").is_file()


# --------------------------------------------------------------------------- outputs that would replace inputs


def test_compare_json_out_naming_its_grid_csv_is_refused(meas_set, run_cli):
    grid = meas_set.parent / "grid.csv"
    before = _digest(meas_set.parent)
    code, _, err = run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--json-out", grid)
    assert code == 2
    _no_traceback(err)
    assert "error LB611: --json-out: file exists and was not written by lbscene" in err or \
        "error LB612: --json-out: output would replace one of this run's inputs" in err
    assert _digest(meas_set.parent) == before


def test_compare_json_out_naming_the_measurement_set_is_an_input(meas_set, run_cli):
    before = _digest(meas_set.parent)
    code, _, err = run_cli("compare", meas_set, "--no-history", "--json-out", meas_set)
    assert code == 2
    assert f"{meas_set}: error LB612: --json-out: output would replace one of this run's inputs" in err
    assert _digest(meas_set.parent) == before


@pytest.mark.parametrize("option", ["--json-out", "--report"])
def test_a_folder_given_for_a_file_output(meas_set, run_cli, option):
    code, _, err = run_cli("compare", meas_set, "--no-history", "--no-diagnose", option, meas_set.parent)
    assert code == 2
    _no_traceback(err)
    assert f"error LB610: {option}: is a folder; expected a file name (expected a file path)" in err


def test_report_and_json_out_replace_their_own_earlier_output_but_not_a_users_file(meas_set, run_cli):
    rep, js = meas_set.parent / "r.html", meas_set.parent / "r.json"
    for _ in range(2):     # the second run replaces what the first wrote
        assert run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--report", rep,
                       "--json-out", js)[0] == 0
    assert LEDGER_NAME in os.listdir(meas_set.parent)
    js.write_text(js.read_text() + " ")                      # edited by the user: now theirs
    code, _, err = run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--json-out", js)
    assert code == 2 and "LB611" in err
    assert js.read_text().endswith(" ")


def test_two_options_naming_one_file(meas_set, run_cli):
    out = meas_set.parent / "x.json"
    code, _, err = run_cli("compare", meas_set, "--no-history", "--report", out, "--json-out", out)
    assert code == 2
    assert "error LB500: --json-out and --report name the same output" in err


def test_plan_out_into_a_read_only_place(meas_set, run_cli):
    code, _, err = run_cli("plan", meas_set, "--out", "/proc/plan.csv")
    assert code == 2
    _no_traceback(err)
    assert "/proc/plan.csv: error LB610: --out: cannot write in the folder '/proc'" in err


# --------------------------------------------------------------------------- render configs


@pytest.fixture
def render_cfg(tmp_path):
    d = tmp_path / "cfg"
    shutil.copytree(REPO / "tests" / "runtimes" / "data", d)
    return d


@pytest.mark.parametrize("case", ["png_names_config", "png_escapes", "o_names_sample"])
def test_render_outputs_are_confined_and_never_replace_inputs(render_cfg, run_cli, case):
    cfg = render_cfg / "tube-gonio.yaml"
    text = cfg.read_text()
    args = ["render", cfg, "--no-input"]
    if case == "png_names_config":
        cfg.write_text(text.replace("png: out/tube-gonio.png", "png: tube-gonio.yaml"))
        want = "error LB612: output.png: output would replace one of this run's inputs"
    elif case == "png_escapes":
        cfg.write_text(text.replace("png: out/tube-gonio.png", "png: ../escaped.png"))
        want = "error LB201: output.png: output path escapes the folder of the file that names it"
    else:
        args += ["-o", render_cfg / "sample-gonio.yaml"]
        want = "error LB612: --out: output would replace one of this run's inputs"
    before = _digest(render_cfg.parent)
    code, _, err = run_cli(*args)
    assert code == 2, err
    _no_traceback(err)
    assert want in err
    if case == "png_names_config":
        assert "tube-gonio.yaml:11:" in err                     # located at the config's output line
    assert _digest(render_cfg.parent) == before


# --------------------------------------------------------------------------- odd input files


def _run(*args, timeout=60, env=None):
    return subprocess.run([sys.executable, "-m", "lbscene", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO, env={**os.environ, **(env or {})})


def test_dev_zero_and_a_fifo_are_refused_at_once(tmp_path):
    fifo = tmp_path / "booth.yaml"
    os.mkfifo(fifo)
    for path, kind in (("/dev/zero", "a device"), (fifo, "a FIFO")):
        p = _run("validate-config", path, timeout=60)     # a hang would time out here
        assert p.returncode == 2
        _no_traceback(p.stderr)
        assert f"error LB012: not a regular file (got {kind}; expected a regular file)" in p.stdout + p.stderr


def test_a_history_that_is_a_fifo_is_not_called_missing(meas_set, run_cli):
    os.mkfifo(meas_set.with_name("meas.history.jsonl"))
    code, out, err = run_cli("history", meas_set)
    assert code == 2
    assert "error LB012: not a regular file (got a FIFO" in err
    assert "does not exist" not in out + err


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_an_unreadable_file_is_not_called_missing(minimal_booth, run_cli):
    f = minimal_booth / "booth.yaml"
    f.chmod(0)
    try:
        code, _, err = run_cli("validate-config", f)
    finally:
        f.chmod(0o644)
    assert code == 2
    assert "error LB013: cannot read the file: permission denied" in err


def test_a_big_plain_document_is_not_called_an_alias_bomb(minimal_booth, run_cli):
    lamp = ("  - {{id: l{i}, type: point, position_mm: [0, 0, 700], spd: {{type: cie_illuminant, name: A}}, "
            "output: {{type: peak_intensity_cd, value_cd: 1}}}}\n")
    text = (minimal_booth / "booth.yaml").read_text()
    head, tail = text.split("lamps:\n", 1)
    tail = tail.split("lighting:", 1)[1]
    (minimal_booth / "booth.yaml").write_text(
        head + "lamps:\n" + "".join(lamp.format(i=i) for i in range(12000)) + "lighting:" + tail)
    code, out, err = run_cli("validate-config", minimal_booth)
    assert code == 2
    assert "alias" not in out + err
    assert "error LB004: document has too many values" in out + err


# --------------------------------------------------------------------------- bounded work


def test_too_many_readings_are_refused_before_any_work(meas_set, run_cli, monkeypatch):
    monkeypatch.setenv("LBSCENE_MAX_READINGS", "20")
    code, _, err = run_cli("compare", meas_set, "--no-history")
    assert code == 2
    assert ("grid.csv:1:1: error LB510: illuminance readings in one measurement set: 35 exceeds the limit "
            "of 20") in err
    assert "hint: raise the limit with the environment variable LBSCENE_MAX_READINGS=N" in err


def test_too_many_point_sources_fail_validation(minimal_booth, run_cli):
    f = minimal_booth / "booth.yaml"
    lamps = "".join(f"  - {{id: t{i}, type: point, position_mm: [{i * 10 - 100}, 0, 700], point_sources: 9000, "
                    "spd: {type: cie_illuminant, name: A}, output: {type: peak_intensity_cd, value_cd: 1}}\n"
                    for i in range(3))
    f.write_text(f.read_text().replace("lighting:\n", lamps + "lighting:\n"))
    code, out, err = run_cli("validate-config", minimal_booth)
    assert code == 2
    assert ("error LB510: point sources over all lamps (the sum of point_sources): 27100 exceeds the limit "
            "of 20000") in out + err


@pytest.mark.parametrize("var,value", [("LBSCENE_MAX_READINGS", "-3"), ("LBSCENE_MAX_PATCHES", "inf"),
                                       ("LBSCENE_CACHE_MAX_MB", "inf")])
def test_environment_variables_are_checked(var, value, minimal_booth, run_cli, monkeypatch):
    monkeypatch.setenv(var, value)
    code, _, err = run_cli("validate-config", minimal_booth)
    assert code == 2
    _no_traceback(err)
    assert f"error LB501: {var} must be" in err


def test_bake_samples_are_bounded(minimal_booth, run_cli):
    code, _, err = run_cli("bake", minimal_booth, "--samples", "1000000000")
    assert code == 2
    _no_traceback(err)
    assert "--samples" in err and "65536" in err


# --------------------------------------------------------------------------- validation catches what would crash


@pytest.mark.parametrize("where,text", [("at the sample", "[0, 0, 0]"), ("in the floor", "[0, 100, 0.2]")])
def test_a_lamp_at_a_receiver_is_a_validation_error(where, text, minimal_booth, run_cli, tmp_path):
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace("type: point\n    position_mm: [0, 0, 700]",
                                       f"type: bulb\n    radius_mm: 10\n    position_mm: {text}"))
    code, out, err = run_cli("validate-config", minimal_booth)
    assert code == 2
    assert "error LB309: lamp 'bulb'" in out + err
    code, _, err = run_cli("build", minimal_booth, "--out", tmp_path / "b")
    assert code == 2 and "LB309" in err
    _no_traceback(err)
    assert not (tmp_path / "b").exists()


def test_an_implausible_reading_is_an_error(meas_set, run_cli):
    g = meas_set.parent / "grid.csv"
    lines = g.read_text().splitlines()
    lines[4] = lines[4].rsplit(",", 1)[0] + ",1e30"
    g.write_text("\n".join(lines) + "\n")
    code, _, err = run_cli("compare", meas_set, "--no-history")
    assert code == 2
    assert "grid.csv:5:" in err and "error LB406: illuminance beyond any light booth" in err


# --------------------------------------------------------------------------- outliers


def test_a_mistyped_reading_is_flagged_and_left_out_of_the_verdict(meas_set, run_cli):
    import json

    g = meas_set.parent / "grid.csv"
    lines = g.read_text().splitlines()
    x, y, e = lines[10].split(",")
    lines[10] = f"{x},{y},{float(e) * 10:.3f}"                  # a dropped decimal point
    g.write_text("\n".join(lines) + "\n")
    code, out, _ = run_cli("compare", meas_set, "--no-history", "--format", "json")
    assert code == 0
    j = json.loads(out)
    assert [(o["line"], o["x_mm"], o["y_mm"]) for o in j["outliers"]] == [(11, float(x), float(y))]
    assert j["outliers_excluded"] is True
    assert j["outlier_note"] == ("fit and verdict computed without 1 outlying reading "
                                 "(--keep-outliers to include them)")
    assert j["n_points"] == 34
    assert j["verdict"] == "none"                 # the closed form is the model: nothing is missing
    code, out, _ = run_cli("compare", meas_set, "--no-history", "--format", "json", "--keep-outliers")
    j = json.loads(out)
    assert j["n_points"] == 35 and j["outliers_excluded"] is False
    assert j["outlier_note"] == "fit and verdict computed with 1 outlying reading included"
    assert j["verdict"] != "none"


def test_no_reading_is_flagged_in_clean_data(meas_set, run_cli):
    import json

    # the outliers are flagged against the declared model before the fit, and the diagnosis
    # (which checks neither) runs after both: without it the same two things are checked
    code, out, _ = run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--format", "json")
    assert code == 0
    j = json.loads(out)
    assert j["outliers"] == [] and j["outlier_note"] is None
    assert j["rmse_percent"] < 1.0                # the model is the closed form


def test_a_users_file_under_the_history_name_is_kept_and_refused_before_the_work(meas_set, run_cli):
    h = meas_set.with_name("meas.history.jsonl")
    h.write_text("my own log, not an lbscene history\n")
    code, _, err = run_cli("compare", meas_set)
    assert code == 2
    assert (f"{h}: error LB611: history file exists and is not an lbscene history; it is left as it is"
            in err)
    assert h.read_text() == "my own log, not an lbscene history\n"
    assert run_cli("compare", meas_set, "--no-history", "--no-diagnose")[0] == 0


# --------------------------------------------------------------------------- ownership at the moment of writing


def _dead_pid() -> int:
    p = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(p.stdout)


def test_only_lbscenes_own_leftovers_of_gone_processes_are_removed(tmp_path):
    """The cleanup removes ``.<name>.lbtmp-<pid>-…`` of a process that is gone (or whose pid now
    belongs to another process), never a name of another pattern, and never a live run's."""
    from lbscene.engine.files.outputs import process_token, write_output

    out = tmp_path / "out.json"
    old = 1_000_000_000                                           # 2001: far older than any age rule
    keep = [tmp_path / ".out.json.old-1", tmp_path / ".out.json.tmp-abcdef", tmp_path / ".out.json.12345678.tmp"]
    keep[0].write_text("the user's backup")
    keep[1].mkdir()
    (keep[1] / "data.txt").write_text("the user's folder")
    keep[2].write_text("mine")
    for p in keep:
        os.utime(p, (old, old))
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        token = process_token(sleeper.pid)
        assert token is not None and len(token) == 8
        live = tmp_path / f".out.json.lbtmp-{sleeper.pid}-{token}-abcd1234"        # a run still going
        live_old = tmp_path / f".out.json.lbtmp-{os.getpid()}-deadbeef"             # this process (old naming)
        reused = tmp_path / f".out.json.lbtmp-{sleeper.pid}-{'0' * 8 if token != '0' * 8 else '1' * 8}-abcd1234"
        dead = tmp_path / f".out.json.lbtmp-{_dead_pid()}-deadbeef"
        for p in (live, live_old, reused, dead):
            p.write_text("half")
        write_output(out, "{}\n")
        assert all(p.exists() for p in keep + [live, live_old])
        assert not dead.exists()                       # its process is gone
        assert not reused.exists()                     # its pid belongs to another process now
    finally:
        sleeper.kill()
        sleeper.wait()
    assert keep[0].read_text() == "the user's backup" and (keep[1] / "data.txt").read_text() == "the user's folder"


def test_a_build_keeps_siblings_named_like_old_temporaries(minimal_booth, tmp_path, run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    backup = tmp_path / ".b.old-1"
    backup.mkdir()
    (backup / "notes.txt").write_text("my copy")
    hidden = tmp_path / ".b.tmp-mywork"
    hidden.mkdir()
    (hidden / "x.txt").write_text("x")
    for p in (backup, hidden):
        os.utime(p, (1_000_000_000, 1_000_000_000))
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    assert (backup / "notes.txt").read_text() == "my copy" and (hidden / "x.txt").read_text() == "x"


def test_a_file_that_appears_after_the_check_is_not_replaced(tmp_path):
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import check_output_file, write_output

    out = check_output_file(tmp_path / "r.json", option="--json-out")     # nothing there yet
    out.write_text("the user's file, saved while the command ran")
    with pytest.raises(LbsceneUserError) as ei:
        write_output(out, "lbscene's output", option="--json-out")
    assert ei.value.diagnostics[0].format() == (
        f"{out}: error LB611: --json-out: file appeared or changed while this command ran; it is left as it is "
        "and the new output was not written")
    assert out.read_text() == "the user's file, saved while the command ran"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]        # no temporary left


def test_a_file_changed_after_the_check_is_not_replaced(tmp_path):
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import check_output_file, write_output

    out = tmp_path / "r.json"
    write_output(out, "first")
    check_output_file(out, option="--json-out")                           # lbscene's: may be replaced
    out.write_text("edited by hand while the command ran")
    with pytest.raises(LbsceneUserError) as ei:
        write_output(out, "second", option="--json-out")
    assert ei.value.diagnostics[0].code == "LB611"
    assert out.read_text() == "edited by hand while the command ran"


@pytest.mark.parametrize("forgery", ["newer_than_ledger", "read_only", "ledger_is_a_link", "ledger_of_another_user"])
def test_a_ledger_is_believed_only_for_files_it_can_vouch_for(tmp_path, forgery):
    """A ledger vouches for a file only while the file matches its sha256 and is not newer than the
    ledger, and only a regular ledger file of the current user is read at all."""
    from lbscene.engine.files.outputs import made_by_lbscene, write_output

    d = tmp_path / "d"
    d.mkdir()
    out = d / "r.json"
    write_output(out, "lbscene's output\n")
    assert made_by_lbscene(out)
    ledger = d / LEDGER_NAME
    if forgery == "newer_than_ledger":                       # rewritten with the same bytes: the user's now
        t = ledger.stat().st_mtime_ns + 5_000_000_000
        os.utime(out, ns=(t, t))
    elif forgery == "read_only":                            # the user protected it
        out.chmod(0o444)
    elif forgery == "ledger_is_a_link":
        elsewhere = tmp_path / "ledger-elsewhere.json"
        ledger.rename(elsewhere)
        ledger.symlink_to(elsewhere)
    else:
        if os.geteuid() != 0:
            pytest.skip("only root can give a file to another user")
        os.chown(ledger, 4321, 4321)
    assert not made_by_lbscene(out)


def test_a_read_only_file_listed_in_a_forged_ledger_is_refused(meas_set, run_cli):
    import hashlib as _h

    plan = meas_set.parent / "plan.csv"
    plan.write_text("my plan\n")
    plan.chmod(0o444)
    sha = _h.sha256(plan.read_bytes()).hexdigest()
    (meas_set.parent / LEDGER_NAME).write_text(json.dumps({"files": {"plan.csv": {"sha256": sha, "size": 8}}}))
    code, _, err = run_cli("plan", meas_set, "--out", plan)
    assert code == 2
    _no_traceback(err)
    assert f"{plan}: error LB611: --out: file is read-only; lbscene does not replace it" in err
    assert plan.read_text() == "my plan\n"


def test_a_symlink_left_for_a_writers_temporary_is_not_moved_into_place(tmp_path):
    """Third-party writers (savefig, OpenEXR, np.save) get a path in a private 0700 folder inside
    the target's folder; what they leave there must be a regular file, never a link."""
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import output_path

    victim = tmp_path / "elsewhere.txt"
    victim.write_text("not lbscene's")
    out = tmp_path / "plots" / "p.png"
    with pytest.raises(LbsceneUserError) as ei:
        with output_path(out, suffix=".png", option="--plot") as tmp:
            private = Path(tmp).parent
            assert private.parent == out.parent
            assert stat.S_IMODE(private.stat().st_mode) == 0o700
            os.symlink(victim, tmp)                        # what a hostile swap leaves
    assert ei.value.diagnostics[0].format() == (
        f"{out}: error LB610: --plot: the writer did not leave a regular file (got a symbolic link)")
    assert not os.path.lexists(out) and victim.read_text() == "not lbscene's"
    assert os.listdir(out.parent) == []


def _attacker_python() -> str | None:
    """A Python another user can run (the system's), for playing the attacker."""
    for p in ("/usr/bin/python3", "/usr/local/bin/python3"):
        if os.path.isfile(p) and os.stat(p).st_mode & stat.S_IXOTH:
            return p
    return None


@pytest.mark.skipif(os.geteuid() != 0 or _attacker_python() is None,
                    reason="needs root to play a second user, and a Python that user can run")
def test_another_user_cannot_swap_a_writers_temporary_for_a_link():
    """In a folder others may write to, another user replaces the temporary a writer is about to
    open by name with a symbolic link to a file of ours: the writer must not follow it."""
    import tempfile

    from lbscene.engine.files.outputs import output_path

    base = Path(tempfile.mkdtemp(prefix="lbscene-shared-", dir="/tmp"))
    try:
        base.chmod(0o755)
        shared = base / "shared"
        shared.mkdir()
        shared.chmod(0o777)
        victim = base / "victim.txt"
        victim.write_text("precious")
        swap = ("import os, sys\nt = sys.argv[1]\n"
                "try:\n    os.unlink(t)\nexcept FileNotFoundError:\n    pass\nos.symlink(sys.argv[2], t)\n")
        out = shared / "p.bin"
        with output_path(out, suffix=".bin") as tmp:
            attack = subprocess.run([_attacker_python(), "-c", swap, str(tmp), str(victim)], user=65534,
                                    group=65534, capture_output=True, text=True, cwd="/")
            Path(tmp).write_bytes(b"lbscene's bytes")         # a writer that opens its path by name
        assert attack.returncode != 0 and "PermissionError" in attack.stderr, attack.stderr
        assert victim.read_text() == "precious"
        assert out.read_bytes() == b"lbscene's bytes" and not out.is_symlink()
    finally:
        shutil.rmtree(base)


# --------------------------------------------------------------------------- build folders: every file, recursively


def test_a_hand_edit_inside_a_build_is_refused_and_kept(minimal_booth, tmp_path, run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    usda = out / "lighting" / "A" / "scene.usda"
    usda.write_text(usda.read_text() + "# my note\n")
    before = _digest(out)
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2
    _no_traceback(err)
    assert (f"{usda}: error LB611: --out: this file was changed since lbscene wrote it; the output folder is "
            "left as it is (expected the file as lbscene wrote it)") in err
    assert _digest(out) == before


def _fake_bake(folder: Path, files: dict) -> None:
    """A bake folder as ``lbscene bake`` leaves it: the products, then the manifest listing them."""
    import hashlib as _h

    folder.mkdir(parents=True)
    for name, text in files.items():
        (folder / name).write_text(text)
    (folder / "manifest.json").write_text(json.dumps({
        "kind": "lbscene.bake_products", "job_hash": "0" * 64,
        "files": {n: _h.sha256(t.encode()).hexdigest() for n, t in files.items()}}))


def test_a_sub_folder_with_a_manifest_is_not_exempt(minimal_booth, tmp_path, run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    sub = out / "mine"
    sub.mkdir()
    (sub / "manifest.json").write_text(json.dumps({"job_hash": "x", "files": {}}))   # it vouches for nothing
    (sub / "notes.txt").write_text("my notes")
    before = _digest(out)
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2
    assert ("error LB611: --out: folder holds files lbscene did not write; it is left as it is "
            "(got mine/notes.txt;") in err
    assert _digest(out) == before


def test_a_rebuild_keeps_the_bakes_inside_the_build(minimal_booth, tmp_path, run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    _fake_bake(out / "bake" / "A", {"pts.exr": "pixels", "job.json": "{}"})
    bake = _digest(out / "bake")
    (minimal_booth / "booth.yaml").write_text(
        (minimal_booth / "booth.yaml").read_text().replace("value_cd: 1000", "value_cd: 1500"))
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 0, err
    assert _digest(out / "bake") == bake                   # hours of Cycles are not thrown away
    # a file of the user's inside the bake: the build folder is left alone
    (out / "bake" / "A" / "notes.txt").write_text("mine")
    before = _digest(out)
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2 and "error LB611: --out: folder holds files lbscene did not write" in err
    assert "bake/A/notes.txt" in err
    assert _digest(out) == before


def test_a_user_file_that_appears_in_the_build_folder_during_the_build_is_kept(minimal_booth, tmp_path,
                                                                               run_cli, monkeypatch):
    from lbscene.engine.scene import build as build_mod

    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0

    def user_saves_a_file(name):
        if name == "build-finish":
            (out / "saved-meanwhile.txt").write_text("mine")

    monkeypatch.setattr(build_mod, "fault_point", user_saves_a_file)
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2
    _no_traceback(err)
    assert "error LB611: --out: folder holds files lbscene did not write; it is left as it is " \
           "(got saved-meanwhile.txt" in err
    assert (out / "saved-meanwhile.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".b.")) == []


def test_a_folder_that_appears_during_the_build_is_kept(minimal_booth, tmp_path, run_cli, monkeypatch):
    from lbscene.engine.scene import build as build_mod

    out = tmp_path / "b"

    def user_makes_the_folder(name):
        if name == "build-finish":
            out.mkdir()
            (out / "mine.txt").write_text("mine")

    monkeypatch.setattr(build_mod, "fault_point", user_makes_the_folder)
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2
    assert "error LB611: --out: folder exists and is not an lbscene output" in err
    assert sorted(os.listdir(out)) == ["mine.txt"]


def test_a_very_deep_folder_inside_a_build_is_refused_without_a_crash(minimal_booth, tmp_path, run_cli):
    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    deep = out
    for _ in range(200):
        deep = deep / "d"
    deep.mkdir(parents=True)
    (deep / "x.txt").write_text("deep")
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2
    _no_traceback(err)
    assert "error LB611: --out: folder holds files lbscene did not write; it is left as it is (got " in err
    assert (deep / "x.txt").read_text() == "deep"


def test_a_history_lbscene_wrote_before_the_ledger_is_still_appended_to(meas_set, run_cli):
    h = meas_set.with_name("meas.history.jsonl")
    assert run_cli("compare", meas_set, "--no-diagnose")[0] == 0
    (meas_set.parent / LEDGER_NAME).unlink()                 # a history from before the ledger
    code, _, err = run_cli("compare", meas_set, "--no-diagnose")
    assert code == 0, err
    assert [json.loads(x)["step"] for x in h.read_text().splitlines()] == [1, 2]


@pytest.fixture(params=["renameat2", "no_renameat2"])
def rename_kind(request, monkeypatch):
    """Run a test with ``renameat2`` and as on a system without it (link + unlink, checked replace)."""
    if request.param == "no_renameat2":
        from lbscene.engine.files import outputs

        monkeypatch.setattr(outputs, "_renameat2", lambda *a: False)
    return request.param


def test_write_time_checks_with_and_without_renameat2(tmp_path, rename_kind):
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import write_output

    out = tmp_path / "r.json"
    write_output(out, "one")
    write_output(out, "two")                                  # its own: replaced
    assert out.read_text() == "two"
    out.write_text("the user's now")
    with pytest.raises(LbsceneUserError) as ei:
        write_output(out, "three")
    assert ei.value.diagnostics[0].code == "LB611"
    new = tmp_path / "new.json"
    new.write_text("appeared")                              # not there when the command started
    with pytest.raises(LbsceneUserError):
        write_output(new, "lbscene's")
    assert out.read_text() == "the user's now" and new.read_text() == "appeared"
    assert sorted(p.name for p in tmp_path.iterdir()) == [LEDGER_NAME, "new.json", "r.json"]


def test_folder_swaps_with_and_without_renameat2(minimal_booth, tmp_path, run_cli, monkeypatch, rename_kind):
    from lbscene.engine.scene import build as build_mod

    out = tmp_path / "b"
    for level in (1000, 1200):                                # new, then replacing its own
        f = minimal_booth / "booth.yaml"
        f.write_text(f.read_text().replace("value_cd: 1000", f"value_cd: {level}"))
        code, _, err = run_cli("build", minimal_booth, "--out", out)
        assert code == 0, err
    ir_hash = json.loads((out / "manifest.json").read_text())["ir_hash"]

    def user_saves_a_file(name):
        if name == "build-finish":
            (out / "saved-meanwhile.txt").write_text("mine")

    monkeypatch.setattr(build_mod, "fault_point", user_saves_a_file)
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace("value_cd: 1200", "value_cd: 1300"))
    code, _, err = run_cli("build", minimal_booth, "--out", out)
    assert code == 2 and "saved-meanwhile.txt" in err
    assert (out / "saved-meanwhile.txt").read_text() == "mine"
    assert json.loads((out / "manifest.json").read_text())["ir_hash"] == ir_hash
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".b.")) == []


def test_a_writers_output_replaces_its_own_earlier_output(tmp_path, rename_kind):
    """The file a path-needing writer replaces is checked against the ledger of the target's folder
    (after the exchange it lies in the writer's private folder)."""
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.outputs import output_path

    out = tmp_path / "x.npy"
    for value in (1.0, 2.0):
        with output_path(out, suffix=".npy", option="--xyz") as tmp:
            np.save(tmp, np.full(3, value))
    np.testing.assert_array_equal(np.load(out), np.full(3, 2.0))
    np.save(out, np.zeros(3))                                    # the user's now
    with pytest.raises(LbsceneUserError):
        with output_path(out, suffix=".npy", option="--xyz") as tmp:
            np.save(tmp, np.full(3, 3.0))
    np.testing.assert_array_equal(np.load(out), np.zeros(3))
    assert sorted(p.name for p in tmp_path.iterdir()) == [LEDGER_NAME, "x.npy"]


def test_a_build_folder_another_lbscene_run_is_writing_into_is_left_alone(minimal_booth, tmp_path, run_cli):
    from lbscene.engine.files.outputs import process_token

    out = tmp_path / "b"
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0
    (out / "bake").mkdir()
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        busy = out / "bake" / f".A.lbtmp-{sleeper.pid}-{process_token(sleeper.pid)}-abcd1234"
        busy.mkdir()                                           # a bake of a run still going
        (busy / "pts.exr").write_text("half")
        code, _, err = run_cli("build", minimal_booth, "--out", out)
        assert code == 2
        assert (f"{out}: error LB611: --out: folder is being written by another lbscene run; it is left as it is "
                f"(got bake/{busy.name}; expected no lbscene run writing into it)") in err
        assert (busy / "pts.exr").read_text() == "half"
    finally:
        sleeper.kill()
        sleeper.wait()
    assert run_cli("build", minimal_booth, "--out", out)[0] == 0       # once it is gone, its leftover goes
    assert not busy.exists()


def test_a_ledger_nested_past_the_json_parser_is_not_believed(meas_set, run_cli, tmp_path):
    """A ``.lbscene-outputs.json`` of 100 000 nested arrays: not believed (no traceback); a new
    output beside it is written, the user's file it might have listed is left alone."""
    out = tmp_path / "nested"
    out.mkdir()
    (out / ".lbscene-outputs.json").write_text("[" * 100_000 + "]" * 100_000)
    (out / "r.json").write_text("the user's own r.json")
    code, _, err = run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--json-out", out / "r.json")
    assert code == 2 and "error LB611: --json-out: file exists and was not written by lbscene" in err
    assert "Traceback" not in err and (out / "r.json").read_text() == "the user's own r.json"
    code, _, err = run_cli("compare", meas_set, "--no-history", "--no-diagnose", "--json-out", out / "new.json")
    assert code == 0, err
    assert json.loads((out / "new.json").read_text())["n_points"] > 0
