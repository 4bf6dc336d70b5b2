"""The output error's first solve starts at latencies over the IMU's range (fit.latency_starts)
and reports where each ended (report.report_lines)."""

from types import SimpleNamespace

import numpy as np
import pytest

from gyrohost.ident.fit import latency_starts
from gyrohost.ident.params import Param
from gyrohost.ident.report import report_lines

EST = SimpleNamespace(imu_period_s=0.01, imu_max_delay_s=0.03)


def params(latency_nominal_s=0.0012):
    return [
        Param("J3", "J3", True, 1.9e-5, "kg m^2"),
        Param("imu_latency", "imu-latency", False, latency_nominal_s, "s", -latency_nominal_s),
    ]


def test_the_starts_cover_the_latencys_range_half_a_period_apart():
    starts = latency_starts(params(), EST)
    latencies = [0.0012 + s[1] for s in starts]
    assert latencies == pytest.approx([0.0, 0.005, 0.01, 0.015, 0.02, 0.025, 0.03], abs=1e-12)
    assert all(s[0] == 0.0 for s in starts)  # the others at their nominal


def test_without_the_latency_one_start_at_the_nominal():
    starts = latency_starts(params()[:1], EST)
    assert len(starts) == 1 and not starts[0].any()


def test_the_report_names_the_lowest_start_and_where_it_ended():
    result = SimpleNamespace(latency_starts=[(0.0, 1880.2, 0.0), (0.015, 1650.1, 0.0155)])
    line = next(x for x in _lines(result) if x.startswith("imu_latency: the first solve"))
    assert "2 latencies from 0.0 to 15.0 ms (costs 1650.1 to 1880.2)" in line
    assert line.endswith("the lowest from 15.0 ms, at 15.50 ms")


def _lines(result):
    """The report of a fit that has nothing but ``result``'s latency starts to tell."""
    from unittest import mock

    from gyrohost.ident import report

    empty = dict(params=[], determined=np.zeros(0, bool), combinations=[], unresolved=[])
    empty.update(scale_valley=None, strings_valley=[], start_line=None, dropped=[])
    for name, value in empty.items():
        setattr(result, name, value)
    result.strong_correlations = list
    result.nfev, result.status = 1, "ok"
    with (
        mock.patch.object(report, "_fit_quality", return_value=[]),
        mock.patch.object(report, "_sigma_notes", return_value=[]),
    ):
        return report_lines(result)
