"""Outputs that cannot be written end in one line naming the file, exit 1, no traceback.

Every command that writes is pointed at a place it cannot write: a path through a
regular file (ENOTDIR: works as root, where chmod does not stop writes) in process, and
a truly read-only folder (chmod 0o555, the command run as the unprivileged user
``nobody`` when the tests run as root: EACCES) through the real ``tactile-studio``
executable. The GUI's writers (confusion export, wellness report, the Record button)
show the same line instead of raising.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.output_faults import fault_line

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")
PREFIX = "tactile-studio: error: "
NOBODY = 65534


@pytest.fixture(scope="module")
def base():
    """A folder the unprivileged user can read (pytest's tmp folders are root-only)."""
    root = Path(tempfile.mkdtemp(prefix="ts-faults-"))
    root.chmod(0o755)
    yield root
    for path in root.rglob("*"):  # read-only folders must be writable again to delete
        if path.is_dir() and not path.is_symlink():
            path.chmod(0o755)
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="module")
def data(base):
    make_dataset_folder(base / "data", participants=3, blocks=2, gestures=GESTURES3)
    assert main(["export", str(base / "data" / "P01.h5"), "--format", "shearsense-csv",
                 "--out", str(base / "csv")]) == 0
    assert main(["train", "--data", str(base / "data"), "--model", "rf", "--preset", "tiny",
                 "--eval", "lopo", "--out", str(base / "run"), "--cache-dir",
                 str(base / "cache"), "--set", "n_estimators=20"]) == 0
    (base / "blocker").write_text("a regular file: nothing can be made under it")
    return base


def one_error_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith(PREFIX)]
    assert len(lines) == 1, err
    return lines[0][len(PREFIX):]


def blocked_commands(d: Path) -> dict[str, list[str]]:
    """Each writing command with its output under the regular file ``blocker``."""
    b = d / "blocker"
    quick_char = ["--set", "speed=0", "--taxels", "B2", "--sequence", "normal",
                  "--param", "dwell_s=0.5", "--param", "normal_steps=4"]
    return {
        "record": ["record", "--device", "simulated", "--seconds", "0.3", "--out", f"{b}/x.h5"],
        "collect": ["collect", "--virtual-participant", "--protocol", "shear9",
                    "--participant", "P01", "--blocks", "1", "--out", f"{b}/sub"],
        "import": ["import", "shearsense", f"{d}/csv/P01_FLAT.csv", "--out", f"{b}/sub"],
        "export-csv": ["export", f"{d}/data/P01.h5", "--format", "shearsense-csv", "--out",
                       f"{b}/sub"],
        "export-npz": ["export", f"{d}/data/P01.h5", "--format", "npz", "--out", f"{b}/sub"],
        "export-trials": ["export", f"{d}/data/P01.h5", "--format", "csv-trials", "--out",
                          f"{b}/sub"],
        "characterise": ["characterise", *quick_char, "--out", f"{b}/char"],
        "calibrate": ["calibrate", "--device", "simulated", "--set", "speed=0", "--sensor",
                      "sim-0", "--auto", "--loads-g", "100,200,300", "--taxels", "B2",
                      "--out", f"{b}/cal.json"],
        "wellness": ["wellness", "--device", "simulated", "--set", "speed=0", "--sensor",
                     "sim-0", "--auto", "--weight-g", "200", "--spots", "B2",
                     "--report", f"{b}/w.html"],
        "train": ["train", "--data", f"{d}/data", "--model", "rf", "--preset", "tiny",
                  "--eval", "lopo", "--cache-dir", f"{d}/cache", "--out", f"{b}/run"],
        "sweep": ["sweep", "--data", f"{d}/data", "--models", "rf", "--preset", "tiny",
                  "--cache-dir", f"{d}/cache", "--out", f"{b}/sweep"],
        "report": ["report", "individual", "--data", f"{d}/data", "--cache-dir", f"{d}/cache",
                   "--out", f"{b}/report"],
        "snapshot": ["snapshot", "--seconds", "0.1", "--out", f"{b}/x.png"],
    }


@pytest.mark.parametrize("name", list(blocked_commands(Path("."))))
def test_every_writing_command_ends_in_one_line(name, data, capsys, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(data / f"appdata-{name}"))
    code = main(blocked_commands(data)[name])
    line = one_error_line(capsys.readouterr().err)
    assert code == 1
    assert line.startswith(f"{data}/blocker"), line
    assert any(cause in line for cause in ("cannot write (Not a directory)", "does not exist",
                                           "not a folder"))


def test_evaluate_and_export_model_in_a_run_folder_they_cannot_write(data, capsys, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(data / "run", run)
    (run / "rescore.json").mkdir()  # where evaluate writes its result: a folder
    assert main(["evaluate", str(run)]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert line == f"{run}/rescore.json: cannot write (Is a directory)"
    (run / "export").write_text("a file where export-model makes its folder")
    assert main(["export-model", str(run), "--format", "onnx"]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert line.startswith(f"{run}/export") and "cannot write" in line


# ---- a real read-only folder: EACCES, as the unprivileged user --------------------------

def run_unprivileged(argv: list[str], base: Path) -> subprocess.CompletedProcess:
    appdata = base / "appdata-nobody"
    appdata.mkdir(exist_ok=True)
    appdata.chmod(0o777)
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(appdata),
           "TACTILE_STUDIO_CACHE_DIR": str(appdata), "HOME": str(appdata),
           "MPLCONFIGDIR": str(appdata), "QT_QPA_PLATFORM": "offscreen",
           "TACTILE_STUDIO_SETTINGS": str(appdata / "settings.ini")}
    exe = [str(Path(sys.executable).with_name("tactile-studio"))]
    if os.geteuid() == 0:  # root writes anywhere: become nobody (setpriv reaches the venv's
        # interpreter where subprocess's own user= switch is refused it)
        if shutil.which("setpriv") is None:
            pytest.skip("running as root without setpriv: no way to drop privileges")
        exe = ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", *exe]
    return subprocess.run([*exe, *argv], capture_output=True, text=True, env=env,
                          cwd=base, timeout=300)


@pytest.fixture(scope="module")
def readonly(data):
    ro = data / "readonly"
    ro.mkdir()
    ro.chmod(0o555)
    run = data / "run-readonly"
    shutil.copytree(data / "run", run)
    for path in [run, *run.rglob("*")]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return data


@pytest.mark.slow  # one process each, as another user
@pytest.mark.parametrize("argv, target", [
    (["export", "data/P01.h5", "--format", "shearsense-csv", "--out", "readonly"],
     "readonly/P01_FLAT.csv"),
    (["export", "data/P01.h5", "--format", "npz", "--out", "readonly"], "readonly/P01_t0000"),
    (["export", "data/P01.h5", "--format", "csv-trials", "--out", "readonly"],
     "readonly/P01_trials.csv"),
    (["evaluate", "run-readonly"], "run-readonly: cannot write in this folder"),
    (["train", "--data", "data", "--model", "rf", "--preset", "tiny", "--eval", "lopo",
      "--cache-dir", "cache-nobody", "--out", "readonly/run"], "readonly/run"),
    (["snapshot", "--seconds", "0.1", "--out", "readonly/x.png"], "readonly/x.png"),
    (["record", "--device", "simulated", "--seconds", "0.3", "--out", "readonly/x.h5"],
     "readonly/x.h5"),
    (["collect", "--virtual-participant", "--protocol", "shear9", "--participant", "P01",
      "--blocks", "1", "--out", "readonly"], "readonly/P01_shear9_"),
    (["import", "shearsense", "csv/P01_FLAT.csv", "--out", "readonly"], "readonly/P01_FLAT.h5"),
    (["characterise", "--set", "speed=0", "--taxels", "B2", "--sequence", "normal",
      "--out", "readonly/char"], "readonly/char"),
    (["wellness", "--device", "simulated", "--set", "speed=0", "--sensor", "sim-0", "--auto",
      "--weight-g", "200", "--spots", "B2", "--report", "readonly/w.html"], "readonly/w.html"),
    (["calibrate", "--device", "simulated", "--set", "speed=0", "--sensor", "sim-0", "--auto",
      "--loads-g", "100,200,300", "--taxels", "B2", "--out", "readonly/cal.json"],
     "readonly/cal.json"),
    (["export-model", "run-readonly", "--format", "onnx"], "run-readonly/export"),
    (["report", "individual", "--data", "data", "--cache-dir", "cache-nobody", "--out",
      "readonly/report"], "readonly/report"),
])
def test_a_read_only_folder_is_one_line_naming_the_file(argv, target, readonly):
    proc = run_unprivileged(argv, readonly)
    line = one_error_line(proc.stderr)
    assert proc.returncode == 1, proc.stderr
    assert line.startswith(target) and "cannot write" in line, line
    assert line.endswith("(Permission denied)"), line


@pytest.mark.slow  # as another user
def test_evaluate_refuses_a_run_folder_it_cannot_write_before_any_work(readonly):
    """It scored every fold and then failed writing rescore.json; now it probes the folder
    first: ``--data`` names no data at all, and the folder is what it is told about."""
    proc = run_unprivileged(["evaluate", "run-readonly", "--data", "no-such-data"], readonly)
    assert proc.returncode == 1, proc.stderr
    assert one_error_line(proc.stderr) == ("run-readonly: cannot write in this folder, where "
                                           "evaluate saves rescore.json (Permission denied)")
    assert "fold P0" not in proc.stdout + proc.stderr  # no fold was scored
    assert sorted(p.name for p in (readonly / "run-readonly").iterdir()) == sorted(
        p.name for p in (readonly / "run").iterdir())  # the probe left nothing behind


# ---- what counts as the environment's fault ------------------------------------------------

def test_fault_line_names_the_file_and_keeps_programming_errors():
    full = OSError(errno.ENOSPC, "No space left on device", "/data/.s1.csv.part")
    assert fault_line(full) == "/data/s1.csv: cannot write (No space left on device)"
    assert fault_line(OSError(errno.EFBIG, "File too large", "/d/x.json.tmp")) == \
        "/d/x.json: cannot write (File too large)"
    h5 = PermissionError(errno.EACCES, "Unable to synchronously create file (unable to open "
                         "file: name = 'ro/x.h5', errno = 13, error message = 'Permission "
                         "denied', flags = 13, o_flags = 242)")
    assert fault_line(h5) == "ro/x.h5: cannot write (Permission denied)"
    assert fault_line(OSError(errno.ENOENT, "No such file or directory",
                              "/nonexistent-folder/x.h5")) == \
        "/nonexistent-folder/x.h5: folder /nonexistent-folder does not exist"
    deep = "/tmp/" + "x/" * 3000 + "y"  # describing it must not raise ENAMETOOLONG itself
    assert fault_line(OSError(errno.ENAMETOOLONG, "File name too long", deep)).endswith(
        "/y: cannot write (File name too long)")
    assert fault_line(OSError(errno.ENOENT, "No such file or directory", deep)).endswith(
        " does not exist")
    # no file named, or an errno that is not about the place: a bug, keeps its traceback
    assert fault_line(OSError(errno.EACCES, "Permission denied")) is None
    assert fault_line(OSError(errno.EBADF, "Bad file descriptor", "/x")) is None
    assert fault_line(ValueError("x")) is None


@pytest.mark.parametrize("argv", [
    ["report", "individual", "--data", "{d}/data", "--cache-dir", "{d}/cache", "--out", "{b}"],
    ["collect", "--virtual-participant", "--protocol", "shear9", "--participant", "P01",
     "--blocks", "1", "--out", "{b}"],
])
def test_a_file_where_the_output_folder_goes_is_named_as_such(argv, data, capsys):
    argv = [a.format(d=data, b=data / "blocker") for a in argv]
    assert main(argv) == 1
    line = one_error_line(capsys.readouterr().err)
    assert line == f"{data}/blocker: cannot write (exists and is not a folder)"


def test_a_health_run_that_cannot_write_its_file_ends_in_the_one_line(tmp_path, monkeypatch):
    """The calibration wizard's run (HealthCheck): its CAL.json place is a folder."""
    from tactile_studio.file_claims import claim
    from tactile_studio.health.calibration import CalibrationSpec
    from tactile_studio.health.health_check import HealthCheck

    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "appdata"))
    with claim(tmp_path / "cal.json"):  # another job of this program writes it meanwhile
        run = HealthCheck("simulated", {"speed": 0}, CalibrationSpec("sim-0", (100, 200, 300),
                                                                     taxels=("B2",)),
                          auto=True, out=str(tmp_path / "cal.json")).start()
        assert run.join(120)
    # the calibration was stored before its file failed: the line says so (no re-measuring)
    assert run.error == (f"{tmp_path}/cal.json: this calibration file is being written "
                         "already by this program (another recording, job or window); "
                         "nothing was written to it; calibration #1 of sim-0 is stored in "
                         "the logbook (active)")
