"""``import`` (shearsense, cost, haart, xdf) and ``export``: files in and out of sessions."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tactile_studio.errors import IncompleteError
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.output_faults import kept_when_full
from tactile_studio.paths import make_out_dir


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("import", help="turn other tools' and datasets' files into sessions",
                       description="Import files as session files (.h5), one per input "
                                   "CSV or per subject. Ctrl-C keeps finished sessions.")
    fmt = p.add_subparsers(dest="import_format", metavar="FORMAT", required=True)
    s = fmt.add_parser("shearsense", help="the old collection software's CSVs")
    s.add_argument("files", nargs="+", help="P<participant>...<FLAT|PILLOW>.csv files")
    s.add_argument("--gestures", metavar="MAP", default=None,
                   help="pressed key -> gesture name: a .toml file, key=Name,... (keys as "
                        "characters or codes, e.g. r=Rub or 114=Rub) or a protocol (cost14, "
                        "or a protocol file); default: shear9's keys")
    s.add_argument("--participant-map", metavar="MAP", default=None,
                   help="file-name participant -> id: a .toml file or old=new,... (names are "
                        "first normalised: upper case, P8 = P08)")
    c = fmt.add_parser("cost", help="the CoST dataset (CoST.csv)")
    c.add_argument("files", nargs=1, metavar="file", help="CoST.csv")
    h = fmt.add_parser("haart", help="the HAART dataset (training.csv, testWITHLABELS.csv)")
    h.add_argument("files", nargs="+", help="training.csv and/or testWITHLABELS.csv")
    x = fmt.add_parser("xdf", help="XDF files (LabRecorder, pyxdf): each tactile stream a "
                                   "session, markers as events and trials, other streams kept")
    x.add_argument("files", nargs="+", help=".xdf files (BIDS names give participant/session)")
    x.add_argument("--participant", default=None,
                   help="participant when the file name has no sub-<label>")
    x.add_argument("--stream", metavar="NAME", default=None,
                   help="the tactile stream by name (default: recognised automatically)")
    x.add_argument("--layout", metavar="L", default=None,
                   help="its layout, e.g. grid-8x8 (default: from its channel count)")
    for q in (s, c, h, x):
        q.add_argument("--out", default=".", help="folder for the session files (default: .)")
        q.add_argument("--force", action="store_true", help="overwrite existing sessions")
        q.set_defaults(func=cmd_import)

    e = sub.add_parser("export", help="export sessions as ShearSense CSV, NPZ, a trial table "
                                      "or XDF")
    e.add_argument("sessions", nargs="+", help="session files (.h5)")
    e.add_argument("--format", required=True,
                   choices=["shearsense-csv", "npz", "csv-trials", "xdf"],
                   help="xdf: frames, events and trials as markers, auxiliary signals "
                        "(the file LabRecorder writes)")
    e.add_argument("--out", default=".", help="output folder (default: .)")
    e.add_argument("--all-trials", action="store_true",
                   help="also export redone and discarded trials (default: ok only)")
    e.add_argument("--grid", default="auto", choices=["auto", "virtual", "physical"],
                   help="npz grid: virtual 11x11 for the shear sensor (auto) or physical")
    e.add_argument("--force", action="store_true", help="overwrite existing files")
    e.set_defaults(func=cmd_export)


class _Bar:
    """A terminal progress bar that can end its line, so that a message printed after
    an error or a finished session starts on a line of its own."""

    def __init__(self, label: str) -> None:
        self.bar = TerminalProgress(label)
        self.open = False

    def __call__(self, fraction: float, message: str = "") -> None:
        self.bar(fraction, message)
        self.open = fraction < 1.0

    def end_line(self) -> None:
        if self.open:
            self.bar.close()
            self.open = False


@contextmanager
def _bar(label: str) -> Iterator[_Bar]:
    bar = _Bar(label)
    try:
        yield bar
    finally:
        bar.end_line()


def cmd_import(args: argparse.Namespace) -> int:
    make_out_dir(args.out)
    from tactile_studio.storage.exchange.importers import import_cost, import_haart
    from tactile_studio.storage.exchange.importers.shearsense import import_shearsense_study
    from tactile_studio.storage.exchange.importers.xdf import XdfReport

    token = CancelToken()
    said = XdfReport()  # xdf: streams without frames, what was imported short, notes
    written: list[Path] = []
    with kept_when_full(written, "session", "imported"), ctrl_c_cancels(token), \
            _bar(f"import {args.import_format}") as bar:
        def done(path: Path) -> None:
            bar.end_line()
            written.append(path)
            print(f"wrote {path}", flush=True)

        if args.import_format == "shearsense":
            out, report = import_shearsense_study(args.files, args.out, args.gestures,
                                                  args.participant_map, bar, token,
                                                  args.force, done)
        elif args.import_format == "xdf":
            from tactile_studio.storage.exchange.importers.xdf import XdfChoice, import_xdf

            choice = XdfChoice(args.participant, args.stream, args.layout)
            out = import_xdf(args.files, args.out, choice, bar, token, args.force, done, said)
        elif args.import_format == "cost":
            out = import_cost(args.files[0], args.out, bar, token, args.force, done)
        else:
            out = import_haart(args.files, args.out, bar, token, args.force, done)
    if args.import_format == "shearsense":
        for line in report.lines():  # its files without frames among them
            print(line)
    elif args.import_format == "xdf":
        # one problem of an import short of its file is the error line itself
        shorts = said.short if len(said.short) > 1 or said.skipped else []
        for line in (*said.skipped, *shorts, *said.notes):
            print(line)
    else:
        from tactile_studio.storage.exchange.importers.datasets import COST, HAART, numbering_line
        print(numbering_line(COST if args.import_format == "cost" else HAART))
    print(f"imported {len(out)} session(s) into {args.out}")
    if args.import_format == "shearsense" and report.no_frames:  # listed above
        raise IncompleteError(f"{len(report.no_frames)} of {len(args.files)} file(s) not "
                              "imported (no frames after the baseline row)")
    if said.skipped:
        raise IncompleteError(f"{len(said.skipped)} tactile stream(s) not imported (no "
                              "samples; listed above)")
    if said.short:
        raise IncompleteError(said.short[0] if len(said.short) == 1 else
                              f"imported short of what the files recorded: "
                              f"{len(said.short)} problems (listed above)")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    make_out_dir(args.out)
    from tactile_studio.storage.exchange.exporters import export_session, shearsense_status_note

    token = CancelToken()
    written: list[Path] = []
    with kept_when_full(written, "file", "exported"), ctrl_c_cancels(token):
        for session in args.sessions:
            with _bar(f"export {Path(session).name}") as bar:
                paths = export_session(session, args.format, args.out, args.all_trials,
                                       args.grid, bar, token, args.force, written.append)
            shown = paths[0] if len(paths) == 1 else f"{len(paths)} files in {args.out}"
            print(f"{session}: wrote {shown}", flush=True)
            note = (shearsense_status_note(session, args.all_trials)
                    if args.format == "shearsense-csv" else None)
            if note:
                print(f"{session}: {note}", flush=True)
    print(f"exported {len(args.sessions)} session(s), {len(written)} file(s)")
    return 0
