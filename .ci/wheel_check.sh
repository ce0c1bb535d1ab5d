#!/usr/bin/env bash
# The wheel is the product: build it, install it into a fresh virtual environment, and run the
# README's quick start from an empty directory. Prints one line on success; the log on failure.
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
log="$work/log"
run() { echo "+ $*" >>"$log"; "$@" >>"$log" 2>&1; }
fail() { cat "$log" >&2; echo "wheel check failed: $*" >&2; exit 1; }

run python -m pip wheel --quiet --no-deps -w "$work/dist" "$repo" || fail "building the wheel"
wheel="$(ls "$work"/dist/ionav_viz-*.whl)"
run python -m venv "$work/venv" || fail "creating the venv"
run "$work/venv/bin/pip" install --quiet torch==2.13.0 "$wheel" || fail "installing the wheel"
mkdir "$work/user" && cd "$work/user"  # an empty directory, away from the checkout
site="$("$work/venv/bin/python" -c 'import ionav_viz, pathlib; print(pathlib.Path(ionav_viz.__file__).parent)')"
case "$site" in "$work/venv/"*) ;; *) fail "ionav_viz imported from $site, not from the venv" ;; esac
touch "$work/marker"
bin="$work/venv/bin"
run "$bin/ionav-viz" replay sharp-cornering -q || fail "replay sharp-cornering"
[ -s recordings/V-sim-sharp-cornering.rrd ] || fail "replay wrote no ./recordings/V-sim-sharp-cornering.rrd"
grep -q "IDNN" <("$bin/python" -c 'import ionav_viz as iv; print(iv.evaluate("sharp-cornering").to_text())') || fail "no IDNN in the report"
COLUMNS=1000 "$bin/ionav-viz" evaluate --scenario all --overview >overview.txt 2>>"$log" || fail "evaluate --scenario all --overview"
grep -q "IDNN (m)" overview.txt || fail "the overview has no IDNN column"
[ "$(grep -c '^[a-z-]*: V-sim-[a-z-]* *57 ' overview.txt)" -eq 5 ] || fail "the overview does not have the five bundled scenarios' drives"
grep -q '^total *285 ' overview.txt || fail "the overview has no total row over the 285 outages (57 per drive after the 30 s warm-up)"
run "$bin/ionav-viz" screenshot recordings/V-sim-sharp-cornering.rrd -o shot.png --time worst --view local || fail "screenshot"
[ -s shot.png ] || fail "screenshot wrote no shot.png"
written="$(find "$site" -newer "$work/marker" -not -path '*/__pycache__*' | head -5)"
[ -z "$written" ] || fail "files were written inside the installed package: $written"
echo "wheel check: $(basename "$wheel") in a fresh venv ran replay, evaluate --scenario all --overview (IDNN column) and screenshot from an empty directory"
