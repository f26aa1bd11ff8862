"""``tactile-studio qc``: the trial checks of issue 46, post hoc, over recorded sessions;
and the model-check options ``collect --qc-model`` shares with it.

Per trial: the signal checks (protocol/quality.py) and the model check (the prompted
gesture not among the model's top k, or its probability below the threshold;
storage/format/trial_checks.py), with the fold of a leave-one-participant-out run that never saw
the trial's participant (out of fold). Exit 0 whether or not trials are flagged; 1 when
the model and the sessions share no gesture. docs/trial-check.md.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.json_output import print_json
from tactile_studio.cli.tables import table
from tactile_studio.errors import UserError
from tactile_studio.protocol.quality import (
    FrameTiming,
    QualitySettings,
    describe,
    quality_settings,
    trial_flags,
)
from tactile_studio.protocol.runner_events import CheckPersonalised, RunnerEvent, TrialEnded
from tactile_studio.protocol.trial_check import (
    DEFAULT_THRESHOLD,
    DEFAULT_TOP_K,
    MISMATCH_FLAG,
    TrialChecker,
    unknown_gestures,
)
from tactile_studio.storage.format.protocol_file import CollectionProtocol, protocol_from_dict
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trial_checks import DEFAULT_PERSONALISE, rule_text
from tactile_studio.storage.format.trials import TrialRecord, TrialStatus, trial_number

if TYPE_CHECKING:
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck, RunChecks
    from tactile_studio.protocol.trial_runner import TrialRunner


def add_qc_options(p: argparse.ArgumentParser, model_flag: str, help_text: str,
                   required: bool = False) -> None:
    """The model and its two settings (``--qc-top-k``/``--top-k``...)."""
    prefix = "--qc-" if model_flag.startswith("--qc") else "--"
    p.add_argument(model_flag, metavar="RUN|MODEL", required=required, help=help_text)
    p.add_argument(f"{prefix}top-k", type=int, default=DEFAULT_TOP_K, metavar="K",
                   help=f"flag also when the prompted gesture is not among the model's top "
                        f"K (default {DEFAULT_TOP_K}: off)")
    p.add_argument(f"{prefix}threshold", type=finite_float, default=DEFAULT_THRESHOLD,
                   metavar="P", help=f"flag when the model's probability of the prompted "
                                     f"gesture is below P (default {DEFAULT_THRESHOLD:g})")


def qc_checker(model: str | None, top_k: int, threshold: float,
               participant: str | None = None) -> TrialChecker | None:
    """The model check of ``--qc-model`` (None without one); a wrong model is one line."""
    if not model:
        return None
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck

    return ModelTrialCheck(model, top_k, threshold, participant)


def qc_personalise(args: argparse.Namespace) -> bool:
    """``--qc-personalise`` / ``--no-qc-personalise`` made concrete: on by default with
    ``--qc-model`` (DEFAULT_PERSONALISE); asked for without a model is one line."""
    asked = getattr(args, "qc_personalise", None)
    if not getattr(args, "qc_model", None):
        if asked:
            raise UserError("--qc-personalise needs --qc-model")
        return False
    return DEFAULT_PERSONALISE if asked is None else bool(asked)


def announce_check(check: TrialChecker, protocol: CollectionProtocol, runner: TrialRunner) -> None:
    """Say which model checks the trials and which gestures it does not score, and
    print each flagged trial as it ends (headless collection)."""
    d = check.describe()
    print(f"trial check: {d.get('model')} (flag when "
          f"{rule_text(int(d.get('top_k') or 0), float(d.get('threshold') or 0))})",
          file=sys.stderr)
    if d.get("adapts"):
        print("trial check: adapted to the participant after each block (their own "
              "statistics, from all their trials so far)", file=sys.stderr)
    unknown = unknown_gestures(check, protocol.gesture_names)
    if unknown:
        print(f"trial check: not scored (the model does not know them): "
              f"{', '.join(unknown)}", file=sys.stderr)

    def flagged(event: RunnerEvent) -> None:
        if isinstance(event, CheckPersonalised):
            print(f"\ntrial check: personalised with {event.trials} trials of the first "
                  f"block ({event.model})", file=sys.stderr)
        if isinstance(event, TrialEnded) and event.flags:
            t = event.trial
            print(f"\ntrial {trial_number(t.index)} ({t.gesture}): {event.reason}",
                  file=sys.stderr)

    runner.add_listener(flagged)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "qc", help="check recorded trials: signal checks and a model of other participants",
        description="Check every trial of the sessions as the collection checks them when "
                    "they end: signal checks (no contact, saturation, a stuck channel, off "
                    "centre...) and a model: flagged when its probability of the prompted "
                    "gesture is below P (or, with --top-k K, the prompted gesture is not "
                    "among its top K). A leave-one-"
                    "participant-out run checks each participant with the fold that never "
                    "saw them. A run trained with --adapt (train's default model) reads "
                    "each participant with their own statistics, taken over all their "
                    "trials given here (per surface when it adapted per person and "
                    "surface; unlabelled: the transductive route train --shots takes with "
                    "a held-out person), where the collection takes them from the blocks "
                    "done so far; --as-trained reads everyone with the training people's. "
                    "Exit 0 whether or not trials are flagged; 1 when the model and the "
                    "sessions share no gesture.")
    p.add_argument("session", nargs="+", help="session file(s) (.h5), imports included")
    add_qc_options(p, "--model", "a run folder (LOPO: out of fold) or RUN/export/<fold>.onnx",
                   required=True)
    p.add_argument("--as-trained", action="store_true",
                   help="do not adapt the model to each participant's statistics")
    p.add_argument("--json", action="store_true",
                   help="print one object per trial as a JSON list")
    p.set_defaults(func=cmd_qc)


def cmd_qc(args: argparse.Namespace) -> int:
    from tactile_studio.learn.deploy.trial_check import RunChecks

    checks = RunChecks(args.model, args.top_k, args.threshold, adapt=not args.as_trained)
    groups: dict[tuple[str, str], list[Path]] = {}
    shared = False
    for path in map(Path, args.session):
        with SessionFile(path) as s:
            gestures = {t.gesture for t in s.trials if t.gesture}
            shared = shared or bool(gestures & checks.known)
            groups.setdefault(checks.group(participant_of(s, path),
                                           str(s.metadata.get("condition") or "")),
                              []).append(path)
    if not shared:
        raise UserError(f"{args.model}: the model knows {', '.join(sorted(checks.known))}; "
                        "the sessions share no gesture with it")
    by_path: dict[Path, list[QcRow]] = {}
    for (participant, _), paths in groups.items():
        by_path.update(group_rows(paths, participant, checks))
    rows = [r for path in dict.fromkeys(map(Path, args.session)) for r in by_path[path]]
    if args.json:
        print_json(rows)
        return 0
    table(["file", "trial", "participant", "prompted", "predicted", "p", "rank", "flags"],
          [[Path(r["file"]).name, r["trial"], r["participant"], r["prompted"],
            r["predicted"] or "-", "-" if r["p_prompted"] is None else f"{r['p_prompted']:.2f}",
            r["rank"] or "-", "; ".join(r["reasons"]) or "ok"] for r in rows],
          right=("trial", "p", "rank"))
    n_flag = sum(1 for r in rows if r["flags"])
    print(f"{n_flag} of {len(rows)} trials flagged ({checks.default.describe()['model']}, "
          f"{rule_text(args.top_k, args.threshold)})", file=sys.stderr)
    return 0


def participant_of(s: SessionFile, path: Path) -> str:
    return str(s.metadata.get("participant") or path.stem)


class QcRow(TypedDict):
    """One trial as ``qc`` reports it (``--json``: one object per trial)."""

    file: str
    trial: int
    participant: str
    prompted: str
    predicted: str | None
    p_prompted: float | None
    rank: int | None
    flags: list[str]
    reasons: list[str]
    out_of_fold: bool
    model: str
    status: str


@dataclass(frozen=True)
class TrialFrames:
    """One trial's frames as the checks read them."""

    raw: np.ndarray
    baseline: np.ndarray
    device_time: np.ndarray
    rate: float


def checked_trials(s: SessionFile) -> list[tuple[TrialRecord, TrialFrames]]:
    """The trials ``qc`` checks (practice and discarded ones left out) with their frames."""
    out = []
    for t in s.trials:
        if t.practice or t.status == TrialStatus.DISCARDED:
            continue
        start, stop = max(0, t.start_sample), min(t.end_sample, s.n_frames)
        if stop - start < 2:
            continue
        dev_t = s.column("device_time", start, stop)
        span = float(dev_t[-1] - dev_t[0])
        out.append((t, TrialFrames(s.raw(start, stop), s.baseline(start), dev_t,
                               (stop - start - 1) / span if span > 0 else 43.0)))
    return out


def group_rows(paths: list[Path], participant: str, checks: RunChecks
               ) -> dict[Path, list[QcRow]]:
    """The rows of one person's sessions (on one surface), checked by their check met
    with all their usable trials there."""
    sessions = [SessionFile(p) for p in paths]
    try:
        trials = [checked_trials(s) for s in sessions]
        usable = [(t, f) for one in trials for t, f in one if t.usable]
        check = checks.meet(participant, sessions[0].layout,
                            [(f.raw, f.baseline, t.gesture) for t, f in usable],
                            [f.rate for _, f in usable])
        return {p: session_rows(s, p, check, one)
                for p, s, one in zip(paths, sessions, trials)}
    finally:
        for s in sessions:
            s.close()


def session_protocol(s: SessionFile) -> CollectionProtocol | None:
    """The protocol a collection stored (its [quality] and forces), None for imports."""
    try:
        return protocol_from_dict(s.metadata["protocol_spec"], "protocol_spec",
                                  check_images=False)
    except (KeyError, UserError):
        return None


def session_rows(s: SessionFile, path: Path, check: ModelTrialCheck,
                 trials: list[tuple[TrialRecord, TrialFrames]]) -> list[QcRow]:
    """One row per trial of session ``s`` (``trials``: :func:`checked_trials`)."""
    participant = participant_of(s, path)
    protocol = session_protocol(s)
    settings = quality_settings(protocol) if protocol else QualitySettings()
    forces = {g.name: g.force for g in protocol.gestures} if protocol else {}
    model = str(check.describe()["model"])
    rows: list[QcRow] = []
    for t, fr in trials:
        prompted = t.gesture
        flags = trial_flags(s.layout, fr.raw, fr.baseline,
                            timing=FrameTiming(fr.device_time, rate_hz=fr.rate),
                            settings=settings, force=forces.get(prompted))
        v = check.check(s.layout, fr.raw, fr.baseline, fr.rate, prompted)
        stored = v.stored("") if v is not None else None
        if v is not None and v.flagged:
            flags.append(MISMATCH_FLAG)
        rows.append({
            "file": str(path), "trial": trial_number(t.index), "participant": participant,
            "prompted": prompted, "predicted": v.top[0][0] if v else None,
            "p_prompted": None if v is None else round(v.p_prompted, 4),
            "rank": None if v is None else v.rank, "flags": flags,
            "reasons": [describe([f], stored) for f in flags],
            "out_of_fold": check.out_of_fold, "model": model,
            "status": t.status.value})
    return rows


__all__ = ["add_qc_options", "announce_check", "checked_trials", "cmd_qc", "qc_checker",
           "qc_personalise"]
