"""`gyrotens bench --quick` as a smoke test: it runs and reports every section (not how fast)."""

import json

import pytest

from gyrohost.cli import main

# Its quick benchmark takes half a minute of one core and asserts no timing: beside the simulated
# rig's real-time tests (tests/conftest.py), whose second core would otherwise idle.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    assert main(["bench", "--quick", "-o", str(out)]) == 0
    return out


def test_report_has_every_section(report):
    text = (report / "report.md").read_text()
    for heading in (
        "## Headline figures",
        "### Recommended settings",
        "## Peers: MuJoCo",
        "## Scaling",
        "## Estimator budget",
        "## Stability at the extremes",
    ):
        assert heading in text
    assert (report / "pareto-0.png").stat().st_size > 0
    assert (report / "scaling.png").stat().st_size > 0


def test_json_carries_the_measurements(report):
    data = json.loads((report / "bench.json").read_text())
    assert data["dbar_rhs"]["fast"] > 0 and data["dbar_rhs"]["reference"] > 0
    assert {r["method"] for r in data["trade"]} >= {"rk4", "dop853", "radau"}
    ok = [r for r in data["trade"] if not r["failure"]]
    assert ok and all(r["node_error_m"] < 1e-2 for r in ok)
    assert any(r["joined"] for r in data["scaling"])
    assert not [r for r in data["extremes"] if r["status"] == "NaN"]
    assert data["ekf"]["FastDynamics"]["jacobian_s"] > 0
