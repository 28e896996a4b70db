"""A sweep's runs keep their warnings off the terminal (counted in each summary, kept in the logs): in the page's
re-run of the worst run (:func:`dsg_hil.sweep.worker.runs_quiet`) and for good in a Dask worker."""

from __future__ import annotations

import logging

from dsg_hil.sweep.worker import RUN_LOGGERS, runs_quiet


def test_runs_quiet_silences_the_runs_warnings_and_restores_them():
    runner, tcu = logging.getLogger("dsg_hil.sim.runner"), logging.getLogger("ecu_stub.runner")
    assert {"dsg_hil", "ecu_stub"} == set(RUN_LOGGERS)
    before = [logging.getLogger(n).level for n in RUN_LOGGERS]
    assert runner.isEnabledFor(logging.WARNING) and tcu.isEnabledFor(logging.WARNING)
    with runs_quiet():
        assert not runner.isEnabledFor(logging.WARNING) and not tcu.isEnabledFor(logging.WARNING)
        assert runner.isEnabledFor(logging.ERROR)  # errors still reach the terminal
    assert [logging.getLogger(n).level for n in RUN_LOGGERS] == before
    assert runner.isEnabledFor(logging.WARNING)
