"""The report at a glance, checked in headless Chromium: tally first, five distinct verdict colours, no raw NaN."""

from __future__ import annotations

import os

import browser
import pytest

from rhi.experiments import ch3, ch7
from rhi.experiments.ch6 import aso_example
from rhi.report import write_report


def test_report_first_screen_in_chromium(tmp_path):
    if not browser.available():
        if os.environ.get("CI"):
            pytest.fail("CI needs Debian's chromium (.ci/run installs it)")
        pytest.skip("no /usr/bin/chromium")
    results = [("ch3", ch3.table_3_1(), {}), ("ch6", aso_example(resolution=21), {}),
               ("ch7", ch7.example_3dof(steps=41), {})]
    path = write_report(results, tmp_path, meta={"mode": "test", "seconds_per_experiment": {"x": 1.0}})
    with browser.Browser(f"file://{path}", width=1280, height=900) as b:
        assert b.wait_for("document.readyState === 'complete'")
        # the tally box opens the page: on the first screen, above the headline table
        top = b.evaluate("document.querySelector('.tally').getBoundingClientRect().top")
        assert 0 < top < 400
        assert b.evaluate("document.querySelector('.tally').getBoundingClientRect().top < "
                          "document.querySelector('table.headline').getBoundingClientRect().top")
        colours = b.evaluate("[...document.querySelectorAll('.tally-cell')].map(e => getComputedStyle(e).backgroundColor)")
        assert len(colours) == 5 and len(set(colours)) == 5
        # chapters with subtotals; metadata collapsed at the end; no raw nan anywhere in the text
        assert b.evaluate("document.querySelectorAll('table.headline tr.chapter').length") >= 3
        assert b.evaluate("document.getElementById('meta').open") is False
        assert not b.evaluate("/\\bnan\\b/i.test(document.body.innerText)")
        shot = b.screenshot()
        assert shot.shape[0] >= 600 and shot.std() > 5  # something is drawn
        if os.environ.get("RHI_REPORT_SCREENSHOT"):  # look at it: RHI_REPORT_SCREENSHOT=/tmp/x.png
            from PIL import Image

            Image.fromarray(shot).save(os.environ["RHI_REPORT_SCREENSHOT"])
