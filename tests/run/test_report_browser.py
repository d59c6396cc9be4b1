"""The report in a real browser: headless Chromium loads it offline, every image decodes,
the tables are there, and a screenshot is saved for a human to look at.

Needs the Debian package ``chromium`` (``/usr/bin/chromium``); skipped without it, failed
without it when ``GATETWIN_REQUIRE_BROWSER`` is set (as CI should). Chromium
is driven directly (no browser download, no Playwright): ``--dump-dom`` on a copy of the
page carrying a small probe script that, after ``load``, writes into ``<body>`` attributes
how many images there are and how many have ``naturalWidth == 0``; ``--screenshot`` on the
page itself. Name resolution is disabled, so a page that needed the network would show
broken images here.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gatetwin.records import read_record
from gatetwin.report import Figure, Report, Table

RECORD_A = Path(__file__).resolve().parents[2] / "src" / "gatetwin" / "data" / "records" / "A.csv"
ARTIFACTS = Path(__file__).resolve().parents[1] / "artifacts"
WINDOW = (1280, 2000)
PROBE = """<script>
window.addEventListener("load", () => {
  const images = Array.from(document.images);
  const body = document.body;
  body.setAttribute("data-images", String(images.length));
  body.setAttribute("data-broken-images",
    String(images.filter((img) => !img.complete || img.naturalWidth === 0).length));
  body.setAttribute("data-tables", String(document.querySelectorAll("table").length));
  body.setAttribute("data-probe", "loaded");
});
</script>
"""


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if os.access("/usr/bin/chromium", os.X_OK) else None


def chromium(binary: str, profile: Path, *args: str) -> subprocess.CompletedProcess[str]:
    command = [
        binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
        "--no-first-run", "--disable-background-networking", "--disable-component-update",
        "--disable-sync", "--disable-extensions", "--hide-scrollbars",
        "--host-resolver-rules=MAP * ~NOTFOUND", f"--user-data-dir={profile}", *args,
    ]  # fmt: skip
    return subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    return buffer.getvalue()


def figures_of_a() -> tuple[bytes, bytes]:
    """Two real figures: A's 3F level with an FOPDT curve, and the residual."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure as MplFigure

    record = read_record(RECORD_A)
    t, level = record.time_s, record.levels_mm["3F"]
    onset = record.steps[0].time_s
    model = 231.2 - 77.0 * (1.0 - np.exp(-np.clip(t - onset - 2.0, 0.0, None) / 71.0))
    out = []
    for kind in ("level", "residual"):
        fig = MplFigure(figsize=(8.0, 3.2), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.subplots()
        if kind == "level":
            ax.plot(t, level, ".", ms=2, color="0.4", label="measured 3F")
            ax.plot(t, model, color="C0", lw=2, label="FOPDT K = -15.4, T = 71 s")
            ax.legend()
        else:
            ax.plot(t, level - model, color="C3", lw=0.8)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("mm")
        ax.grid(True, alpha=0.5)
        out.append(_png(fig))
    return out[0], out[1]


def build_report(folder: Path) -> Path:
    level_png, residual_png = figures_of_a()
    report = Report("gatetwin report", subtitle="browser test: condition A, gauge 3F")
    report.add_section(
        "Step response, condition A",
        "The reference study's Table 2 against a least-squares FOPDT fit.",
        Table(
            ("gauge", "K published (mm/mm)", "K ours (mm/mm)", "T published (s)", "within 5 %"),
            [
                ("1D", -15.41, -15.36, 71.5, True),
                ("3F", -15.27, -15.36, 71.2, True),
                ("5H", -15.39, -14.2, 70.8, False),
            ],
            "Published vs ours",
        ),  # fmt: skip
        Figure(level_png, "Measured level at 3F and the FOPDT model"),
        Figure(residual_png, "Residual, measured minus model"),
    )
    report.add_section("Validation", "One more table.", Table(("fmu", "fit %"), [("a.fmu", 94.1)]))
    return report.write(folder / "report.html")


@pytest.fixture(scope="module")
def browser() -> str:
    binary = find_chromium()
    if binary is None:
        reason = "no Chromium found (install the Debian package: apt-get install -y chromium)"
        if os.environ.get("GATETWIN_REQUIRE_BROWSER"):  # CI sets it: never skip silently there
            pytest.fail(reason)
        pytest.skip(reason)
    return binary


def test_report_loads_in_chromium_with_every_image_decoded(browser: str, tmp_path: Path) -> None:
    page = build_report(tmp_path)
    html = page.read_text(encoding="utf-8")
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    run = chromium(browser, tmp_path / "profile", "--virtual-time-budget=5000", "--dump-dom",
                   probe.as_uri())  # fmt: skip
    body = re.search(r"<body[^>]*>", run.stdout)
    assert run.returncode == 0 and body, f"chromium failed: {run.stderr[-2000:]}"
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(0)))
    assert attrs.get("data-probe") == "loaded", body.group(0)
    assert attrs["data-images"] == "2" and attrs["data-broken-images"] == "0", body.group(0)
    assert attrs["data-tables"] == "2"
    assert "Published vs ours" in run.stdout and "-15.27" in run.stdout


def test_report_screenshot_is_saved_and_not_blank(browser: str, tmp_path: Path) -> None:
    from matplotlib.image import imread

    page = build_report(tmp_path)
    shot = tmp_path / "report.png"
    run = chromium(browser, tmp_path / "profile", f"--window-size={WINDOW[0]},{WINDOW[1]}",
                   f"--screenshot={shot}", page.as_uri())  # fmt: skip
    assert run.returncode == 0 and shot.is_file(), f"chromium failed: {run.stderr[-2000:]}"
    print(f"\nreport screenshot: {shot}")
    if ARTIFACTS.is_dir() and os.access(ARTIFACTS, os.W_OK):
        shutil.copyfile(shot, ARTIFACTS / "report.png")
        print(f"report screenshot copied to {ARTIFACTS / 'report.png'}")
    pixels = imread(shot)[..., :3]
    assert pixels.shape[:2] == (WINDOW[1], WINDOW[0])
    not_white = np.any(pixels < 0.9, axis=-1)
    assert 0.02 < not_white.mean() < 0.9  # text, tables and plots on a white page
    reddish = (pixels[..., 0] > 0.6) & (pixels[..., 1] < 0.4) & (pixels[..., 2] < 0.4)
    bluish = (pixels[..., 2] > 0.5) & (pixels[..., 0] < 0.3)
    assert reddish.sum() > 100 and bluish.sum() > 100  # the plots' C3 and C0 lines are drawn
