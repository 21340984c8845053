"""The product's files replaced as one unit (jsbsim_calib.core.commit): a write killed half way
leaves the old set or the new one after recover(); hand edits of a generated aircraft are
refused unless --force, which keeps a backup; temporary sandboxes do not outlive their run.
Real files, real generate, real processes killed."""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
from contextlib import nullcontext
from pathlib import Path

import pytest

from jsbsim_calib.cli import main
from jsbsim_calib.core import commit as commit_mod
from jsbsim_calib.core.commit import commit, recover
from jsbsim_calib.core.tempdirs import PREFIX, sweep_stale
from jsbsim_calib.factors import FactorSet
from jsbsim_calib.generate import build
from jsbsim_calib.jsbsim.product import AircraftPaths, recover_product
from jsbsim_calib.jsbsim.simulator import Simulator

REPO = Path(__file__).resolve().parents[1]


def copy_root(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    for d in ("aircraft", "engine", "scripts"):
        shutil.copytree(src / d, dst / d, ignore=shutil.ignore_patterns("backup"))
    for d in ("airfoils", "data"):
        (dst / d).symlink_to(src / d, target_is_directory=True)
    return dst


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(f"*{commit_mod.TMP_MARK}*")]


def failing_replace(monkeypatch, fail_at: int, exc=OSError):
    """os.replace as the commit sees it, raising on call ``fail_at`` (1: the journal's rename,
    which decides the commit; 2: the first target's)."""
    calls = []
    real = os.replace

    def replace(a, b):
        calls.append(b)
        if len(calls) == fail_at:
            raise exc(f"simulated failure renaming onto {b}")
        real(a, b)
    monkeypatch.setattr(commit_mod.os, "replace", replace)
    return calls


@pytest.fixture
def three(tmp_path):
    files = {tmp_path / n: f"old {n}\n".encode() for n in ("a.xml", "b.xml", "c.json")}
    for p, d in files.items():
        p.write_bytes(d)
    return files, {p: d.replace(b"old", b"new") for p, d in files.items()}, tmp_path / ".journal.json"


def state(files) -> set[bytes]:
    return {p.read_bytes().split()[0] for p in files}


def test_failure_after_the_first_rename_is_finished_by_recover(three, monkeypatch):
    old, new, journal = three
    failing_replace(monkeypatch, 3)
    with pytest.raises(OSError, match="simulated"):
        commit(new, journal, backup=journal.parent / "backup")
    monkeypatch.undo()
    assert state(old) == {b"old", b"new"} and journal.is_file()         # a mix until recovered
    assert recover(journal, list(old)) == "finished"
    assert {p: p.read_bytes() for p in old} == new
    assert not journal.exists() and not leftovers(journal.parent)
    assert {p.name: p.read_bytes() for p in (journal.parent / "backup" / "1").iterdir()} == \
        {p.name: d for p, d in old.items()}


def test_failure_before_the_journal_leaves_the_old_set(three, monkeypatch):
    old, new, journal = three
    failing_replace(monkeypatch, 1)
    with pytest.raises(OSError, match="simulated"):
        commit(new, journal)
    monkeypatch.undo()
    assert {p: p.read_bytes() for p in old} == old
    assert not journal.exists() and not leftovers(journal.parent)
    assert recover(journal, list(old)) is None


def test_backups_keep_the_last_few(three):
    old, new, journal = three
    for k in range(5):
        commit({p: d + str(k).encode() for p, d in new.items()}, journal, backup=journal.parent / "backup", keep=3)
    assert sorted(d.name for d in (journal.parent / "backup").iterdir()) == ["3", "4", "5"]
    assert (journal.parent / "backup" / "5" / "a.xml").read_bytes() == b"new a.xml\n3"


def test_one_run_keeps_one_backup_of_the_files_as_they_stood_before_it(three):
    """Issue 26: the commits of one run (calibrate --stage all writes three times) share one
    backup, of each file as it stood before the run, and rotate out no older backup; a file
    the run's first commit left alone is saved when a later commit replaces it."""
    old, new, journal = three
    folder = journal.parent / "backup"
    for k in range(3):                                        # three earlier runs
        commit({p: d + str(k).encode() for p, d in new.items()}, journal, backup=folder, keep=3)
    before = {p: p.read_bytes() for p in old}
    a, b, c = sorted(old)
    run = commit_mod.new_run()
    first = commit({a: b"run 1", b: before[b]}, journal, backup=folder, keep=3, run=run)   # b: unchanged
    second = commit({a: b"run 2", b: b"run 2"}, journal, backup=folder, keep=3, run=run)
    third = commit({a: b"run 3", b: b"run 3", c: b"run 3"}, journal, backup=folder, keep=3, run=run)
    assert first.backup == second.backup == third.backup == folder / "4"
    assert sorted(d.name for d in folder.iterdir()) == ["2", "3", "4"]
    assert {p.name: (folder / "4" / p.name).read_bytes() for p in old} == {p.name: d for p, d in before.items()}
    nxt = commit({a: b"next run"}, journal, backup=folder, keep=3, run=commit_mod.new_run())
    assert nxt.backup == folder / "5" and (folder / "5" / a.name).read_bytes() == b"run 3"


def test_the_stages_of_one_calibrate_run_keep_one_backup_of_the_product(tmp_path):
    """write_calibrated three times in one run (the main job's stage 1, 2a and 2b writes): one
    backup, holding the product as it stood before the run."""
    from jsbsim_calib.jsbsim.product import read_calibration, write_calibrated
    root = copy_root(REPO, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    before = {p.name: p.read_bytes() for p in (paths.aircraft_xml, paths.propeller_xml, paths.calibration)}
    run = commit_mod.new_run()
    factors = read_calibration(paths)
    for stage, k_cdi in (("steady", 1.01), ("trims", 1.02), ("dynamic", 1.03)):
        done = write_calibrated(root, "c172", factors.updated({"K_cdi": k_cdi, "K_CT_scale": k_cdi}), stage, {},
                                run=run)
    assert [d.name for d in paths.backups.iterdir()] == [done.backup.name] == ["1"]
    assert {n: (done.backup / n).read_bytes() for n in before} == before


KILLER = """
import os, signal, sys
from pathlib import Path
import jsbsim_calib.core.commit as c
from jsbsim_calib.generate import generate
calls, real = [], os.replace
def replace(a, b):
    calls.append(b)
    if len(calls) == {kill_at}:
        os.kill(os.getpid(), signal.SIGKILL)
    real(a, b)
c.os.replace = replace
generate("c172", Path(sys.argv[1]), baseline=True)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kill_at, expect", [(1, "old"), (3, "new")])
def test_generate_killed_mid_commit_leaves_old_or_new_set(generated_root, tmp_path, kill_at, expect):
    """A real process killed (SIGKILL) while `generate --baseline` replaces a calibrated c172:
    before its journal is in place (old set) or after the aircraft file's rename (new set)."""
    root = copy_root(generated_root, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    old = {p: p.read_bytes() for p in paths.product_files if p.is_file()}
    r = subprocess.run([sys.executable, "-c", KILLER.format(kill_at=kill_at), str(root)], capture_output=True)
    assert r.returncode == -signal.SIGKILL, r.stderr.decode()[-2000:]
    now = {p: p.read_bytes() for p in old}
    if expect == "new":
        assert now[paths.aircraft_xml] != old[paths.aircraft_xml]       # renamed before the kill ...
        assert now[paths.propeller_xml] == old[paths.propeller_xml]     # ... this one not: a mix
        assert recover_product(paths) == "finished"
    else:
        assert now == old
        assert recover_product(paths) == "rolled back"
    assert not leftovers(root) and not paths.journal.exists()
    want = old if expect == "old" else {**old, **{Path(p): d for p, d in build("c172", root, baseline=True).files.items()}}
    assert {p: p.read_bytes() for p in old} == want
    with Simulator(root, "c172") as sim:                               # the set loads and is consistent
        assert (sim.factors == FactorSet()) == (expect == "new") and sim.new_exec().load_model("c172")


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


@pytest.mark.slow
def test_hand_edit_refused_then_forced_with_a_backup(generated_root, tmp_path, capsys):
    root = copy_root(generated_root, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    _edit(paths.aircraft_xml, "</metrics>", "  <!-- my note -->\n    <location name=\"EYEPOINT\" unit=\"IN\">"
          " <x> 37 </x> <y> -14 </y> <z> 42 </z> </location>\n  </metrics>")
    edited = paths.aircraft_xml.read_bytes()
    assert main(["--root", str(root), "--quiet", "generate", "c172"]) == 2
    err = capsys.readouterr().err
    assert "edited by hand" in err and "my note" in err and "EYEPOINT" in err and "--force" in err, err
    assert "Traceback" not in err
    assert paths.aircraft_xml.read_bytes() == edited and not paths.backups.exists()

    assert main(["--root", str(root), "--quiet", "generate", "c172", "--force"]) == 0
    out = capsys.readouterr()
    assert "dropped" in out.err and "EYEPOINT" in out.err
    backup = paths.backups / "1"
    assert f"backup of the replaced files: {backup}" in out.out
    assert (backup / "c172.xml").read_bytes() == edited
    assert paths.aircraft_xml.read_bytes() == (generated_root / "aircraft" / "c172" / "c172.xml").read_bytes()
    assert main(["--root", str(root), "--quiet", "generate", "c172"]) == 0       # no longer a hand edit


@pytest.mark.slow
def test_a_calibration_value_set_by_hand_is_no_hand_edit(generated_root, tmp_path, capsys):
    """Values are the calibration's to change: generate rewrites them from calibration.json
    (naming the factor) without --force."""
    root = copy_root(generated_root, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    text = paths.aircraft_xml.read_text()
    start = text.index("> calibration/K_cdi <")
    value_at = text.rindex('value="', 0, start) + len('value="')
    paths.aircraft_xml.write_text(text[:value_at] + "1.1" + text[text.index('"', value_at):])
    assert main(["--root", str(root), "--quiet", "generate", "c172"]) == 0
    assert "K_cdi = 1.1 differs from calibration.json" in capsys.readouterr().err
    assert paths.aircraft_xml.read_bytes() == (generated_root / "aircraft" / "c172" / "c172.xml").read_bytes()


SANDBOX = """
import os, signal, sys
from pathlib import Path
from jsbsim_calib.jsbsim.simulator import Simulator
sim = Simulator(Path(sys.argv[1]), "c172")          # never closed
print(sim._box, flush=True)
if sys.argv[2] == "kill":
    os.kill(os.getpid(), signal.SIGKILL)
raise SystemExit(3)
"""


@pytest.mark.parametrize("how", ["exit", "kill"])
def test_sandboxes_do_not_outlive_their_run(generated_root, tmp_path, how):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = subprocess.run([sys.executable, "-c", SANDBOX, str(generated_root), how], capture_output=True, text=True,
                       env={**os.environ, "TMPDIR": str(tmp)})
    box = Path(r.stdout.strip())
    assert box.is_relative_to(tmp), r.stderr[-2000:]
    if how == "exit":
        assert r.returncode == 3 and not list(tmp.iterdir())
    else:
        assert r.returncode == -signal.SIGKILL and box.is_dir()     # no exit handler ran ...
        assert [d.name for d in sweep_stale(tmp)] == [box.parent.name]  # ... the next run sweeps it
        assert box.parent.name.startswith(PREFIX) and not list(tmp.iterdir())


CALIBRATION_KILLER = """
import os, pickle, signal, sys
import jsbsim_calib.cli as cli
import jsbsim_calib.core.commit as c
from pathlib import Path
WRITES = (".commit-journal.json", "c172.xml", "c172_propeller.xml", "calibration.json")
calls, real = [], os.replace
def replace(a, b):
    if Path(b).name in WRITES and str(b).startswith(sys.argv[1]):   # the product's renames, not the sandbox's
        calls.append(b)
        if len(calls) == {kill_at}:
            os.killpg(0, signal.SIGKILL)
    real(a, b)
c.os.replace = replace
# stage 2b from the committed product is the same bits in each of the three kill runs: the first
# computes it (the real run_dynamic) and keeps it for the others, which write it
computed, run_dynamic = Path(sys.argv[3]), cli.run_dynamic
def kept(*args, **kw):
    if computed.is_file():
        return pickle.loads(computed.read_bytes())
    res = run_dynamic(*args, **kw)
    tmp = computed.with_name(f"{{computed.name}}.{{os.getpid()}}.tmp")
    tmp.write_bytes(pickle.dumps(res))
    os.rename(tmp, computed)
    return res
cli.run_dynamic = kept
cli.main(["--root", sys.argv[1], "--quiet", "--executor", "serial", "calibrate", "c172", "--stage", "dynamic",
          "--start", "current", "--report-dir", sys.argv[2]])
"""


@pytest.fixture(scope="session")
def stage2b_kept(tmp_path_factory) -> Path:
    """Where the kill runs keep stage 2b's result: one file per test session (shared by xdist's
    workers, whose base folders sit in the session's)."""
    base = tmp_path_factory.getbasetemp()
    return (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "stage2b_current.pkl"


def _calibrate_dynamic(root: Path, reports: Path) -> None:
    """Stage 2b from the current factors (--start current): from its stated start (the default)
    it rewrites the committed product's bytes, which would write nothing."""
    assert main(["--root", str(root), "--quiet", "--executor", "serial", "calibrate", "c172", "--stage", "dynamic",
                 "--start", "current", "--report-dir", str(reports), "--exit-zero"]) == 0


@pytest.mark.slow
@pytest.mark.parametrize("kill_at", [1, 2, 3])
def test_calibration_killed_at_each_write_leaves_a_consistent_aircraft(tmp_path, kill_at, stage2b_kept):
    """`calibrate c172 --stage dynamic` (the committed C172) killed (SIGKILL) at each rename of
    its write: the journal's (1), then the first product files that change (the aircraft,
    calibration.json and, where stage 2b's K_Ip moved, the propeller it is baked into). The next
    reader finds the old set (1) or the new one (2, 3), never a mix; the aircraft loads. Stage 2b
    itself runs once in the session (the same result each time); each run writes it."""
    root = copy_root(REPO, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    old = {p: p.read_bytes() for p in paths.product_files if p.is_file()}
    r = subprocess.run([sys.executable, "-c", CALIBRATION_KILLER.format(kill_at=kill_at), str(root),
                        str(tmp_path / "reports"), str(stage2b_kept)], capture_output=True, start_new_session=True)
    assert r.returncode == -signal.SIGKILL, r.stderr.decode()[-2000:]
    with pytest.warns(UserWarning, match="interrupted write") if kill_at > 1 else nullcontext():
        assert recover_product(paths) == ("rolled back" if kill_at == 1 else "finished")
    now = {p: p.read_bytes() for p in old}
    assert not leftovers(root) and not paths.journal.exists()
    if kill_at == 1:
        assert now == old
    else:                                  # the files of the write, all new; the rest untouched
        written = {paths.aircraft_xml, paths.calibration}
        assert all(now[p] != old[p] for p in written)
        assert all(now[p] == old[p] for p in old if p not in written | {paths.propeller_xml})
    with Simulator(root, "c172") as sim:   # refuses files of different writes (check_consistent)
        assert sim.new_exec().load_model("c172")


@pytest.mark.slow
def test_hand_edits_survive_calibrate_and_generate(tmp_path, capsys):
    """A comment and a function added by hand and a factor changed by hand: `calibrate` keeps
    the comment and the function and names the factor it overwrites (backup kept); `generate`
    then refuses, listing the lines it would drop, and leaves the file as it was."""
    root = copy_root(REPO, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    _edit(paths.aircraft_xml, "</metrics>", "  <!-- my hand note -->\n  </metrics>")
    _edit(paths.aircraft_xml, "<aerodynamics>", "<aerodynamics>\n    <function name=\"aero/my-hand-term\">"
          " <product> <property>aero/qbar-psf</property> <value>0.0</value> </product> </function>")
    text = paths.aircraft_xml.read_text()
    value_at = text.rindex('value="', 0, text.index("> calibration/K_cdi <")) + len('value="')
    paths.aircraft_xml.write_text(text[:value_at] + "1.1" + text[text.index('"', value_at):])

    _calibrate_dynamic(root, tmp_path / "reports")
    err = capsys.readouterr().err
    assert "K_cdi = 1.1 differs from calibration.json" in err, err     # stage 2b does not fit it: kept, said so
    assert "'dynamic' stage keeps it and records it" in err, err
    after = paths.aircraft_xml.read_text()
    assert "<!-- my hand note -->" in after and 'name="aero/my-hand-term"' in after
    assert (paths.backups / "1" / "c172.xml").read_text().count("my-hand-term") == 1

    assert main(["--root", str(root), "--quiet", "generate", "c172"]) == 2
    err = capsys.readouterr().err
    assert "would drop" in err and "my hand note" in err and "my-hand-term" in err and "Traceback" not in err
    assert paths.aircraft_xml.read_text() == after
    with Simulator(root, "c172") as sim:
        assert sim.new_exec().load_model("c172")


def test_a_model_switch_set_by_hand_is_kept_and_said_so(tmp_path, recwarn):
    """The slipstream switches are the user's: a stage starts from the file's value and keeps it
    (jsbsim_calib.calibration.workflow.run_steady), so the warning says it is kept and recorded, not
    overwritten; a fitted factor set by hand is named as overwritten."""
    from jsbsim_calib.factors import switches
    from jsbsim_calib.jsbsim.aircraft import read_factors
    from jsbsim_calib.jsbsim.product import read_calibration, write_calibrated
    root = copy_root(REPO, tmp_path / "root")
    paths = AircraftPaths(root, "c172")
    _edit(paths.aircraft_xml, '<property value="0" persistent="true"> calibration/K_slip </property>',
          '<property value="1" persistent="true"> calibration/K_slip </property>')
    cdi = re.search(r'<property value="[^"]+" persistent="true"> calibration/K_cdi </property>',
                    paths.aircraft_xml.read_text()).group(0)               # the committed value, whatever it is
    _edit(paths.aircraft_xml, cdi, '<property value="1.1" persistent="true"> calibration/K_cdi </property>')
    declared = read_factors(paths.aircraft_xml)
    assert switches(declared)["K_slip"] == 1.0 and switches(declared)["K_cdi"] == 1.0   # the switch, cdi neutral
    stage_result = read_calibration(paths).updated({"K_slip": 1.0})
    done = write_calibrated(root, "c172", stage_result, "trims", {})
    named = [str(w.message) for w in recwarn]
    assert done.hand_set == ["K_cdi"] and any("K_cdi = 1.1" in m and "overwrites it" in m for m in named)
    assert [m for m in named if "K_slip" in m] == [m for m in named if "K_slip = 1" in m and "keeps it" in m] != []
    assert read_factors(paths.aircraft_xml)["K_slip"] == 1.0 and read_calibration(paths)["K_slip"] == 1.0
