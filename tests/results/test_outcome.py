"""dsg_hil.results.outcome.Summary: every key of the JSON document reachable the same way (issue 35, item 10:
``summary.max_plate_temp_c`` worked, ``summary.rollback_m`` raised AttributeError)."""

from __future__ import annotations

import copy
import json
import pickle

import pytest

from dsg_hil.sim.run import unstarted_summary
from dsg_hil.results.outcome import Summary


@pytest.fixture()
def summary(tmp_path) -> Summary:
    """A summary as a run writes it (one of zero periods: every key there), read back, a caller's key added."""
    path = tmp_path / "s.json"
    unstarted_summary("interrupted", path, "creep", "lockstep", "virtual:x", 10.0, 0)
    return Summary.from_json({**json.loads(path.read_text(encoding="utf-8")), "tcu_counts": {"sent": 3}})


def test_every_key_of_the_document_is_an_attribute_and_an_item(summary):
    document = summary.as_json()
    assert {"rollback_m", "creep_time_s", "mu_CH_first_slip", "frames", "tcu_counts"} <= set(document)
    for key, value in document.items():
        assert getattr(summary, key) == value == summary[key], key
    assert summary.rollback_m == 0.0 and summary.tcu_counts == {"sent": 3}
    assert {"rollback_m", "tcu_counts", "stop_reason"} <= set(dir(summary))


def test_a_key_it_lacks_is_an_attribute_error_and_copies_still_work(summary):
    with pytest.raises(AttributeError, match="no attribute 'rollback_mm'"):
        summary.rollback_mm  # noqa: B018
    assert not hasattr(summary, "rollback_mm")
    for twin in (copy.deepcopy(summary), pickle.loads(pickle.dumps(summary))):
        assert twin == summary and twin.rollback_m == summary.rollback_m
