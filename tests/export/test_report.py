"""The run report: one self-contained HTML page, checked as a file and in a real browser.

The browser check runs headless Chromium (Debian package ``chromium``; ``.ci/run`` installs
it): the page loads with no console errors, every section is in the rendered DOM, and the
screenshot is not blank. Where Chromium is absent that test skips.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess

import pytest
from PIL import Image

from hybridteam.cli import main
from hybridteam.export.report import SECTIONS
from tests.conftest import EXAMPLES, FIXTURES

TEAM = FIXTURES / "acceptance" / "corridor_carry.yaml"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    assert (
        main(
            ["run", str(TEAM), "-o", str(out), "--duration", "6", "--progress", "none", "--report"]
        )
        == 0
    )
    return out / "report.html"


def test_the_report_is_one_self_contained_page(report, capsys):
    page = report.read_text(encoding="utf-8")
    for section in SECTIONS:
        assert f"<section id='{section}'>" in page, section
    # nothing is fetched: no script, no external source, stylesheet or image
    assert "<script" not in page
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", page)
    assert "data:image/gif;base64," in page
    assert "corridor-carry" in page and "class='ok'>ok<" in page  # 6 s: no arrival yet


def test_report_writes_the_page_of_a_run_folder(report, tmp_path, capsys):
    page = tmp_path / "page.html"
    assert main(["report", str(report.parent), "-o", str(page), "--no-animation"]) == 0
    assert capsys.readouterr().out == f"wrote {page}\n"
    text = page.read_text(encoding="utf-8")
    assert "<section id='timeline'>" in text and "data:image/gif" not in text
    animation = text[text.index("<section id='animation'>") :]
    assert animation[: animation.index("</section>")].endswith(
        "<p>Skipped (<code>--no-animation</code>); <code>hybridteam animate trace.json</code> "
        "draws it.</p>"
    )
    assert main(["report", str(report.parent), "-o", str(tmp_path / "page.pdf")]) == 2
    assert "a report is written as .html or .htm" in capsys.readouterr().err


def test_run_report_without_the_animation(tmp_path, capsys):
    """``run --report --no-animation``: the page says the animation was skipped; without
    --report the flag would do nothing, and is refused."""
    out = tmp_path / "run"
    assert (
        main(
            [
                "run",
                str(EXAMPLES / "automata" / "thermostat.yaml"),
                "-o",
                str(out),
                "--progress",
                "none",
                "--no-views",
                "--report",
                "--no-animation",
            ]
        )
        == 0
    )
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "Skipped (<code>--no-animation</code>)" in page and "data:image/gif" not in page
    capsys.readouterr()
    assert (
        main(
            [
                "run",
                str(EXAMPLES / "automata" / "thermostat.yaml"),
                "-o",
                str(tmp_path / "other"),
                "--no-animation",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "--no-animation leaves the animation out of the report: give it with --report" in err
    assert "Traceback" not in err and not (tmp_path / "other").exists()


def test_a_folder_that_is_not_a_run_or_a_study_is_refused(tmp_path, capsys):
    (tmp_path / "trace.json").write_text("{}")
    assert main(["report", str(tmp_path)]) == 2
    assert "no summary.json" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium is not installed")
def test_the_report_renders_in_headless_chromium(report, tmp_path):
    common = [
        "chromium",
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--enable-logging=stderr",
        "--v=0",
    ]
    dom = subprocess.run(
        [*common, "--dump-dom", report.as_uri()], capture_output=True, text=True, timeout=120
    )
    assert dom.returncode == 0, dom.stderr[-2000:]
    for section in SECTIONS:
        assert f'<section id="{section}">' in dom.stdout, section
    console = [line for line in dom.stderr.splitlines() if "CONSOLE" in line]
    assert console == []
    shot = tmp_path / "page.png"
    done = subprocess.run(
        [*common, "--window-size=1200,4000", f"--screenshot={shot}", report.as_uri()],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and shot.is_file(), done.stderr[-2000:]
    with Image.open(shot) as im:
        colours = im.convert("RGB").resize((300, 1000)).getcolors(maxcolors=1 << 16)
    assert colours is not None and len(colours) > 50  # drawn figures, not a blank page


def test_the_report_lists_requirement_verdicts(tmp_path):
    """The thermostat holds its comfort band; ``x <= 21.9`` fails on the first heating:
    from 19 towards 30 at rate K = 0.1, x = 30 - 11 exp(-K t) reaches 21.9 at
    t = ln(11/8.1)/K."""
    text = (EXAMPLES / "automata" / "thermostat.yaml").read_text()
    team = tmp_path / "thermostat.yaml"
    team.write_text(text + "  tight: always(x <= 21.9)\n")
    out = tmp_path / "run"
    assert (
        main(["run", str(team), "-o", str(out), "--progress", "none", "--no-views", "--report"])
        == 0
    )
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "<section id='requirements'>" in page
    rows = re.findall(r"<tr><td>0</td><td>(\w+)</td><td class='(\w+)'>([^<]*)", page)
    assert [(name, cls) for name, cls, _ in rows] == [("comfort", "ok"), ("tight", "bad")]
    t = float(re.search(r"violated at t = ([0-9.e+-]+)", page).group(1))
    assert t == pytest.approx(math.log(11 / 8.1) / 0.1, abs=1e-5)
