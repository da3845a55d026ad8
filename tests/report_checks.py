"""The checks of a finished ``fhnn reproduce`` report folder, shared by the report tests
(tests/test_reproduce.py) and ``benchmarks/quick_reproduction.py``, which stands in for them in the
default test run: every table in three formats, every figure, the Markdown report, and the
self-contained HTML rendered in headless Chromium with every image decoded. A failed check raises
``AssertionError``."""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
from pathlib import Path


def render(html: Path, tmp: Path) -> str:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise AssertionError("headless Chromium is needed (Debian package 'chromium'; .ci/run installs it)")
    cmd = [
        chromium,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp / 'chromium-profile'}",
        "--virtual-time-budget=10000",
        "--dump-dom",
        html.as_uri(),
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True).stdout


def check_report(out: Path, tmp_path: Path, t4: set[str]) -> None:
    """Every table in three formats, the paper column present, numbers finite or marked diverged;
    every figure; the Markdown report; the self-contained HTML, every image decoded in headless
    Chromium."""
    for key in ("T1", "T2", "T3", "T4", "T5", "T6"):
        record = json.loads((out / "tables" / f"{key}.json").read_text())
        assert set(record) == {"provenance", "cells"} and record["provenance"]["source"], key
        rows = record["cells"]
        assert rows, key
        for r in rows:
            assert "paper" in r
            assert (r["mean"] is not None and math.isfinite(r["mean"])) or r["diverged"] > 0, r
        md = (out / "tables" / f"{key}.md").read_text()
        assert "paper" in md or key == "T6"
        assert (
            (out / "tables" / f"{key}.csv").read_text().startswith("table,data,model,horizon,metric,mean,std")
        )
    t1 = json.loads((out / "tables" / "T1.json").read_text())["cells"]
    assert any(r["paper"] == 1.07e-4 for r in t1)  # the paper's FHNN RMSE at 1 s beside ours
    assert {r["data"] for r in json.loads((out / "tables" / "T4.json").read_text())["cells"]} == t4
    for stem in ("flow", "rollouts", "errors_vs_horizon", "ablations"):
        for ext in ("png", "svg"):
            path = out / "figures" / f"{stem}_solid_body_vortex.{ext}"
            assert path.stat().st_size > 5000, path
    assert (out / "figures" / "flow_solid_body_vortex.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = (out / "report.md").read_text()
    assert "### T1" in report and "### T6" in report and "![rollouts_solid_body_vortex]" in report
    html = (out / "index.html").read_text()
    assert "src='figures/" not in html and html.count("data:image/png;base64,") == 4
    dom = render(out / "index.html", tmp_path)
    total = re.search(r'data-images-total="(\d+)"', dom)
    loaded = re.search(r'data-images-loaded="(\d+)"', dom)
    assert total and loaded, dom[:500]
    assert int(total.group(1)) == 4 and int(loaded.group(1)) == 4
    assert "T1: FHNN vs Neural ODE" in dom
