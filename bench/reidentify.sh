#!/bin/sh
# Re-identify the TCU calibration on the current plant: record the identification runs (eleven of creep,
# 44 short torque handovers, 34 launches meant to be handed over to a cool CH: heavy, cold, at low slip, at high
# pressure or slow and steep, 27 of which are with today's TCU; ecu_stub/data/identification) in lock-step with the
# bundled ecu-stub and its current calibration, then fit and write the calibration, with the commit and calibration
# the logs were recorded with in its header (identify --provenance).
#
#   bench/reidentify.sh LOGDIR [CALIBRATION_OUT]   (from the repository root; default out: the shipped file)
#   bench/reidentify.sh --check LOGDIR             record the runs, fit nothing: exit 1 if the shipped
#                                                  calibration's predictor exceeds its own prediction_error_k
#
# PYTHON: the interpreter (default: python). About 3.5 min on one core (1 min creep runs, 2.5 min handovers and
# heavy launches, fit).
# Re-run after any plant change, then
# tests/sim/test_closed_loop.py, tests/ecu_stub and tests/paper (docs/safety.md, the thermal bound).
set -eu
check=
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
logs=${1:?usage: bench/reidentify.sh [--check] LOGDIR [CALIBRATION_OUT]}
out=${2:-ecu_stub/data/calibration.toml}
py=${PYTHON:-python}
mkdir -p "$logs"
commit=$(git rev-parse --short=12 HEAD)$(git diff --quiet HEAD -- dsg_hil ecu_stub || echo "+changes")
cal=$(sha256sum ecu_stub/data/calibration.toml | cut -c1-12)
for scenario in ecu_stub/data/identification/*.toml; do
    name=$(basename "$scenario" .toml)
    # the parameters a run sets: the --set options of its documented command (one '#   dsg-hil run' line)
    if [ "$(grep -c '^#   dsg-hil run ' "$scenario")" != 1 ]; then
        echo "$scenario: not exactly one documented '#   dsg-hil run' line" >&2
        exit 2
    fi
    sets=$(grep '^#   dsg-hil run ' "$scenario" | grep -o -- '--set [^ ]*' | tr '\n' ' ')
    echo "recording $name $sets"
    set -f  # the --set options split into words, not globbed
    # shellcheck disable=SC2086
    "$py" -m dsg_hil run -i virtual -q --scenario "$scenario" $sets --log "$logs/$name.log"
    set +f
done
if [ -n "$check" ]; then
    exec "$py" -m ecu_stub.identify "$logs"/*.log --check
fi
# the short torque-handover runs (handover_*) and launches on a cool CH (map_*): for the friction map, not the
# thermal fits (identify --map-only)
"$py" -m ecu_stub.identify $(ls "$logs"/*.log | grep -v -e /handover_ -e /map_) \
    --map-only "$logs"/handover_*.log "$logs"/map_*.log --write "$out" \
    --provenance "recorded by bench/reidentify.sh at commit $commit with ecu_stub/data/calibration.toml sha256 $cal..."
