"""Every built-in estimator on the public real logs of the test suite's corpus (``tests/data/real/``,
issue 59), in the shape of ``real_imu_logs.py``'s table, from one table of how each log is read
(``tests/data/real/corpus.json``, which the envelope tests read too)::

    python benchmarks/real_corpus.py                      # the table, 10 / 30 / 60 s outages
    python benchmarks/real_corpus.py --record             # and record the 10 and 30 s means as the tests' envelopes
    python benchmarks/real_corpus.py --json-dir DIR       # one JSON per log, as results_table.py --real-logs takes
    python benchmarks/real_corpus.py --write-docs docs/real-imu-logs.md   # regenerate the page's corpus section

``--record`` rewrites ``corpus.json``'s envelopes with what this version measures: run it in the
commit that improves a result, never to make a worse one pass. ``--write-docs`` replaces what lies
between the page's ``<!-- corpus:start -->`` and ``<!-- corpus:end -->`` lines.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

from _cli import add_debug, run
from real_imu_logs import ESTIMATORS, gap_row, measure, row

import ionav_viz as iv
from ionav_viz.core.errors import InputError
from ionav_viz.core.fileio import atomic_write_bytes

CORPUS_DIR = Path(__file__).resolve().parent.parent / "tests" / "data" / "real"
CORPUS_FILE = CORPUS_DIR / "corpus.json"
#: The outage lengths the tests hold (s), of the ones measured.
ENVELOPE_LENGTHS = ("10", "30")
START, END = "<!-- corpus:start -->", "<!-- corpus:end -->"


def measure_entry(entry: dict, lengths: list[float]) -> dict:
    """``real_imu_logs.measure`` on one corpus log, read as its entry says."""
    log = dict(entry.get("log", {}))
    truth = log.pop("truth_topic", None)
    start = time.perf_counter()
    result = measure(CORPUS_DIR / entry["file"], lengths, truth, entry.get("max_sigma_m"), log or None)
    result["seconds"] = round(time.perf_counter() - start, 1)
    return result


def envelope_of(result: dict) -> dict:
    """The 10 and 30 s means per estimator (% of distance, 2 decimals) where outages were scored."""
    out = {}
    for length in ENVELOPE_LENGTHS:
        cell = result["lengths"].get(length, {})
        means = {name: round(float(cell[name]), 2) for name in ESTIMATORS if cell.get(name) is not None}
        if means:
            out[length] = means
    return out


def markdown(corpus: dict, results: dict[str, dict]) -> str:
    """The page's corpus section: the logs, then the table and gins against the INS DR."""
    lines = [f"Measured by `python benchmarks/real_corpus.py --write-docs docs/real-imu-logs.md` ({platform.machine()}, "
             f"Python {platform.python_version()}, ionav-viz {iv.__version__}); do not edit by hand.", "",
             "| log | file (tests/data/real) | IMU and receiver | seconds to measure |", "|---|---|---|---|"]
    for name, entry in sorted(corpus["logs"].items()):
        lines.append(f"| {name} | `{entry['file']}` | {entry['grade']} | {results[name].get('seconds', '')} |")
    lines += ["", "Final position error as a share of the distance driven, IMU only, mean over the outages tiled after the "
              "30 s warm-up:", "", "| log | `gins` 10 s | 30 s | 60 s | INS DR 10 s / 30 s | best other at 10 s | outages (10 s) |",
              "|---|---|---|---|---|---|---|"]
    lines += [row({**results[name], "log": name}) for name in sorted(results)]
    keys = ["10", "30", "60"]
    lines += ["", "`gins` minus the INS DR, points of the distance driven, mean [95 % interval, paired bootstrap over the outages]:", "",
              "| log | " + " | ".join(f"{k} s" for k in keys) + " |", "|---|" + "---|" * len(keys)]
    lines += [gap_row({**results[name], "log": name}, keys) for name in sorted(results)]
    return "\n".join(lines) + "\n"


def check_page(page: Path) -> str:
    """The page's text, refused (before any measurement) without the two marker lines."""
    try:
        text = page.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{page}: cannot be read ({exc.__class__.__name__})", "give the docs page to regenerate",
                         param="--write-docs") from None
    if START not in text or END not in text:
        raise InputError(f"{page}: no '{START}' ... '{END}' lines to write the corpus section between",
                         "add the two lines where the section belongs", param="--write-docs")
    return text


def write_docs(page: Path, section: str) -> None:
    head, rest = check_page(page).split(START, 1)
    tail = rest.split(END, 1)[1]
    atomic_write_bytes(page, (head + START + "\n" + section + END + tail).encode())


def main() -> None:
    parser = add_debug(argparse.ArgumentParser(description=__doc__.splitlines()[0]))
    parser.add_argument("--record", action="store_true", help="record the 10 and 30 s means as the tests' envelopes")
    parser.add_argument("--json-dir", type=Path, help="write one JSON per log here (results_table.py --real-logs)")
    parser.add_argument("--write-docs", type=Path, metavar="PAGE", help="regenerate the page's corpus section")
    parser.add_argument("--only", help="only these logs of the corpus, comma-separated")
    args = parser.parse_args()
    corpus = json.loads(CORPUS_FILE.read_text())
    names = sorted(corpus["logs"]) if not args.only else [n.strip() for n in args.only.split(",")]
    unknown = [n for n in names if n not in corpus["logs"]]
    if unknown:
        raise InputError(f"--only: {', '.join(unknown)} not in {CORPUS_FILE}", f"choose from {', '.join(sorted(corpus['logs']))}",
                         param="--only")
    if args.json_dir and not args.json_dir.is_dir():
        raise InputError(f"--json-dir: {args.json_dir} is not a folder", "create it first", param="--json-dir")
    if args.write_docs:
        check_page(args.write_docs)
    print("| log | `gins` 10 s | 30 s | 60 s | INS DR 10 s / 30 s | best other at 10 s | outages (10 s) |")
    print("|---|---|---|---|---|---|---|")
    results = {}
    for name in names:
        result = measure_entry(corpus["logs"][name], [10.0, 30.0, 60.0])
        results[name] = result
        print(row({**result, "log": name}), f"({result['seconds']} s)", flush=True)
        if args.json_dir:
            atomic_write_bytes(args.json_dir / f"{name}.json", json.dumps(result, indent=1, default=float).encode())
        if args.record:
            corpus["logs"][name]["envelope"] = envelope_of(result)
    if args.record:
        atomic_write_bytes(CORPUS_FILE, (json.dumps(corpus, indent=1, ensure_ascii=False) + "\n").encode())
        print(f"recorded the envelopes of {len(names)} logs in {CORPUS_FILE}", file=sys.stderr)
    if args.write_docs:
        write_docs(args.write_docs, markdown({"logs": {n: corpus["logs"][n] for n in names}}, results))


if __name__ == "__main__":
    run(main)
