"""Open a report's ``index.html`` in headless Chromium, check it as a reader's browser shows it, save screenshots.

``python -m mocapbench.experiments.browser_check REPORT_DIR [--out SHOTS_DIR] [--widths 1280,1024]``

For each window width the page is loaded with a small checker script (in a temporary copy of ``index.html``
beside it, so that relative image paths resolve; the copy is removed afterwards) and Chromium's DOM after the
load is read back (``--dump-dom``). The checks, each a failure when it does not hold:

* every ``<img>`` has loaded (``complete`` and ``naturalWidth > 0``);
* nothing overflows the page width: the document is not wider than the window, and no element outside a
  scrolling table box (``.table-scroll``) or a ``<pre>`` sticks out to the right;
* every in-page link (``href="#..."``) has its target;
* figure text is at least 10 px high as shown: the smallest figure font (10 pt at :data:`plots.DPI`) times
  the image's displayed / natural width;
* the page text itself is at least 10 px (computed font sizes).

Screenshots (PNG) of the top of the page and of the main sections (each from a copy that starts at the section) go to
``SHOTS_DIR`` (default ``REPORT_DIR/screenshots``). Chromium is found as ``$MOCAPBENCH_CHROMIUM``, ``chromium``,
``chromium-browser`` or ``google-chrome``; on Debian: ``apt-get install chromium``.
"""

from __future__ import annotations

import argparse
import html
import json
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["find_chromium", "check_report", "BrowserCheck", "ChromiumNotFound", "SECTIONS", "player_facts",
           "player_screenshot", "pixels_near", "colour_share"]

SECTIONS = ("headline-which-codec-to-pick", "rate-distortion", "distributions-over-clips", "what-animators-see",
            "pictures", "all-rate-distortion-points", "data-and-method")
MIN_TEXT_PX = 10.0
SMALLEST_FIGURE_FONT_PT = 10.0

_CHECKER = """
<script>
window.addEventListener("load", function () {
  var out = {images: [], offenders: [], missingAnchors: [], scrollingTables: 0, smallText: []};
  var width = document.documentElement.clientWidth;
  out.windowWidth = width;
  out.documentWidth = document.documentElement.scrollWidth;
  out.documentHeight = document.documentElement.scrollHeight;
  document.querySelectorAll("img").forEach(function (img) {
    var rect = img.getBoundingClientRect();
    out.images.push({src: img.getAttribute("src"), complete: img.complete, naturalWidth: img.naturalWidth,
                     shownWidth: rect.width, right: rect.right});
  });
  document.querySelectorAll("body *").forEach(function (el) {
    if (el.closest(".table-scroll") || el.closest("pre") || el.id === "mcb-check") return;
    var rect = el.getBoundingClientRect();
    if (rect.width > 0 && rect.right > width + 1) {
      out.offenders.push(el.tagName.toLowerCase() + ": " + (el.textContent || el.getAttribute("src") || "")
                         .trim().slice(0, 60) + " (right edge " + Math.round(rect.right) + " px)");
    }
  });
  document.querySelectorAll(".table-scroll").forEach(function (box) {
    if (box.scrollWidth > box.clientWidth + 1) out.scrollingTables += 1;
    if (box.getBoundingClientRect().right > width + 1) out.offenders.push("table box wider than the page");
  });
  document.querySelectorAll("a[href^='#']").forEach(function (a) {
    var id = decodeURIComponent(a.getAttribute("href").slice(1));
    if (!document.getElementById(id)) out.missingAnchors.push(id);
  });
  var seen = {};
  document.querySelectorAll("p, li, td, th, figcaption, h1, h2, h3, code, a").forEach(function (el) {
    var size = parseFloat(getComputedStyle(el).fontSize);
    if (size < %(min_px)s && el.textContent.trim() && !seen[el.tagName]) {
      seen[el.tagName] = true;
      out.smallText.push(el.tagName.toLowerCase() + " " + size + " px");
    }
  });
  var pre = document.createElement("pre");
  pre.id = "mcb-check";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>
"""


_SECTION_CUT = """
<script>
(function () {
  var heading = document.getElementById("%(id)s");
  while (heading && heading.previousElementSibling) heading.previousElementSibling.remove();
})();
</script>
"""


class ChromiumNotFound(RuntimeError):
    """No Chromium binary: the message says how to install one."""


@dataclass
class BrowserCheck:
    """Findings of :func:`check_report`: ``failures`` empty means the page passed."""

    report: Path
    failures: list[str] = field(default_factory=list)
    findings: list[str] = field(default_factory=list)
    screenshots: list[Path] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failures


def find_chromium() -> str:
    """Path of a Chromium binary (``$MOCAPBENCH_CHROMIUM`` first)."""
    for name in (os.environ.get("MOCAPBENCH_CHROMIUM"), "chromium", "chromium-browser", "google-chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    raise ChromiumNotFound("no Chromium found (tried $MOCAPBENCH_CHROMIUM, chromium, chromium-browser, "
                           "google-chrome); on Debian/Ubuntu: apt-get install -y chromium")


def _chromium(binary: str, *args: str, timeout: float = 90.0) -> subprocess.CompletedProcess:
    command = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--mute-audio",
               "--no-first-run", "--allow-file-access-from-files", "--disable-dev-shm-usage", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


def _page_facts(binary: str, index: Path, width: int) -> dict:
    """Load a checker copy of ``index`` at ``width`` px and return the checker's JSON."""
    from mocapbench.experiments import plots

    text = index.read_text()
    checker = _CHECKER.replace("%(min_px)s", str(MIN_TEXT_PX))
    copy = index.with_name(f".browser-check-{os.getpid()}-{width}.html")
    copy.write_text(text.replace("</body>", checker + "</body>", 1))
    try:
        result = _chromium(binary, f"--window-size={width},1200", "--virtual-time-budget=20000", "--dump-dom",
                           copy.resolve().as_uri())
    finally:
        copy.unlink(missing_ok=True)
    match = re.search(r'<pre id="mcb-check">(.*?)</pre>', result.stdout, re.S)
    if not match:
        tail = (result.stderr or "").strip().splitlines()[-3:]
        raise RuntimeError(f"Chromium returned no check result for {index} at {width} px: {' | '.join(tail)}")
    facts = json.loads(html.unescape(match.group(1)))
    facts["figure_px_per_pt"] = plots.DPI / 72.0
    return facts


def check_report(report: str | Path, shots: str | Path | None = None,
                 widths: tuple[int, ...] = (1280, 1024)) -> BrowserCheck:
    """Run the checks of the module docstring on ``report/index.html`` and save screenshots.

    Raises
    ------
    ChromiumNotFound
        If no Chromium binary exists.
    FileNotFoundError
        If ``report`` holds no ``index.html``.
    """
    report = Path(report)
    index = report / "index.html"
    if not index.is_file():
        raise FileNotFoundError(f"{report}: no index.html (not a report folder)")
    binary = find_chromium()
    check = BrowserCheck(report=report)
    for width in widths:
        facts = _page_facts(binary, index, width)
        where = f"at {width} px"
        broken = [i["src"] for i in facts["images"] if not i["complete"] or i["naturalWidth"] <= 0]
        check.failures += [f"{where}: image did not load: {src}" for src in broken]
        if facts["documentWidth"] > facts["windowWidth"] + 1:
            check.failures.append(f"{where}: the page is {facts['documentWidth']} px wide in a "
                                  f"{facts['windowWidth']} px window (horizontal scrolling)")
        check.failures += [f"{where}: overflows the page: {o}" for o in facts["offenders"][:10]]
        check.failures += [f"{where}: link to a missing anchor #{a}" for a in facts["missingAnchors"]]
        check.failures += [f"{where}: page text under {MIN_TEXT_PX:g} px: {t}" for t in facts["smallText"]]
        smallest = float("inf")
        for image in facts["images"]:
            if image["naturalWidth"] > 0:
                scale = image["shownWidth"] / image["naturalWidth"]
                shown = SMALLEST_FIGURE_FONT_PT * facts["figure_px_per_pt"] * scale
                smallest = min(smallest, shown)
                if shown < MIN_TEXT_PX:
                    check.failures.append(f"{where}: figure text {shown:.1f} px in {image['src']} "
                                          f"(shown {image['shownWidth']:.0f} of {image['naturalWidth']} px)")
        check.findings.append(
            f"{where}: {len(facts['images'])} images, all loaded: {not broken}; page {facts['documentWidth']} px wide "
            f"in a {facts['windowWidth']} px window, {facts['documentHeight']} px high; "
            f"{facts['scrollingTables']} wide table(s) scroll inside their box; smallest figure text "
            f"{smallest:.1f} px; {len(facts['offenders'])} overflowing element(s); "
            f"{len(facts['missingAnchors'])} broken in-page link(s)")
    out = Path(shots) if shots else report / "screenshots"
    out.mkdir(parents=True, exist_ok=True)
    text = index.read_text()
    for name in ("top", *SECTIONS):
        if name != "top" and f'id="{name}"' not in text:
            continue
        target = out / f"{name}.png"
        # Headless Chromium screenshots the top of the page even after scrolling to an anchor, so the copy
        # for a section drops everything before the section's heading.
        cut = "" if name == "top" else _SECTION_CUT.replace("%(id)s", name)
        copy = index.with_name(f".browser-shot-{os.getpid()}-{name}.html")
        copy.write_text(text.replace("</body>", cut + "</body>", 1))
        try:
            result = _chromium(binary, f"--window-size={widths[0]},1400", "--virtual-time-budget=10000",
                               f"--screenshot={target}", copy.resolve().as_uri())
        finally:
            copy.unlink(missing_ok=True)
        if not target.exists():
            check.failures.append(f"screenshot {target.name} was not written: {result.stderr.strip()[-200:]}")
        else:
            check.screenshots.append(target)
    return check


def _page_uri(page: Path, fragment: str) -> str:
    return Path(page).resolve().as_uri() + (f"#{fragment}" if fragment else "")


def player_facts(page: str | Path, fragment: str = "", width: int = 1100) -> dict:
    """What a player page (:mod:`mocapbench.experiments.player`) shows after it loads at ``#fragment``.

    Returns the JSON the page's script writes into ``<pre id="facts">``: ``entry``, ``frame``, ``worstFrame``,
    ``worstJoint``, ``worstPage`` (the decoded worst joint's centre in page pixels, on the whole-body view),
    ``worstColour``, ``original`` and ``decoded`` (the skeletons' colours).
    """
    result = _chromium(find_chromium(), f"--window-size={width},1000", "--virtual-time-budget=10000", "--dump-dom",
                       _page_uri(page, fragment))
    match = re.search(r'<pre id="facts">(.*?)</pre>', result.stdout, re.S)
    if not match or not match.group(1).strip():
        tail = (result.stderr or "").strip().splitlines()[-3:]
        raise RuntimeError(f"Chromium returned no player facts for {page}: {' | '.join(tail)}")
    return json.loads(html.unescape(match.group(1)))


def player_screenshot(page: str | Path, png: str | Path, fragment: str = "", width: int = 1100,
                      height: int = 1000) -> Path:
    """Screenshot (PNG, ``width`` x ``height`` px, the top of the page) of a player page loaded at ``#fragment``."""
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    result = _chromium(find_chromium(), f"--window-size={width},{height}", "--virtual-time-budget=10000",
                       f"--screenshot={png.resolve()}", _page_uri(page, fragment))
    if not png.exists():
        raise RuntimeError(f"screenshot {png} was not written: {result.stderr.strip()[-200:]}")
    return png


def _rgb(colour: str) -> tuple[int, int, int]:
    """``#rrggbb`` or ``rgb(r,g,b)`` as integers."""
    if colour.startswith("#"):
        return tuple(int(colour[i:i + 2], 16) for i in (1, 3, 5))
    return tuple(int(v) for v in re.findall(r"\d+", colour)[:3])


def _pixels(png: str | Path):
    import matplotlib.image

    image = matplotlib.image.imread(str(png))  # (H, W, 3 or 4) floats in [0, 1]
    return (image[..., :3] * 255).round().astype(int)


def pixels_near(png: str | Path, xy: tuple[float, float], colour: str, radius: int = 3, tolerance: int = 40) -> int:
    """How many pixels within ``radius`` px of ``xy`` (page pixels, as the screenshot) are within ``tolerance`` of
    ``colour`` on every channel."""
    pixels = _pixels(png)
    x, y = int(round(xy[0])), int(round(xy[1]))
    box = pixels[max(0, y - radius):y + radius + 1, max(0, x - radius):x + radius + 1]
    return int((abs(box - _rgb(colour)) <= tolerance).all(axis=-1).sum())


def colour_share(png: str | Path, colour: str, tolerance: int = 12) -> float:
    """Share of the screenshot's pixels within ``tolerance`` of ``colour`` on every channel."""
    pixels = _pixels(png)
    return float((abs(pixels - _rgb(colour)) <= tolerance).all(axis=-1).mean())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mocapbench.experiments.browser_check",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("report", help="a report folder (holding index.html)")
    parser.add_argument("--out", help="folder for the screenshots (default: REPORT/screenshots)")
    parser.add_argument("--widths", default="1280,1024", help="window widths in px, comma-separated")
    args = parser.parse_args(argv)
    try:
        widths = tuple(int(w) for w in args.widths.split(","))
        check = check_report(args.report, args.out, widths)
    except (ChromiumNotFound, FileNotFoundError, ValueError, RuntimeError) as error:
        print(f"browser_check: error: {error}", file=sys.stderr)
        return 2
    for line in check.findings:
        print(line)
    for path in check.screenshots:
        print(f"screenshot: {path}")
    for failure in check.failures:
        print(f"FAIL {failure}")
    print("browser check passed" if check.ok else f"browser check failed: {len(check.failures)} problem(s)")
    return 0 if check.ok else 1


if __name__ == "__main__":
    sys.exit(main())
