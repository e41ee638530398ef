"""report.html in a real browser: headless Chromium (Debian's ``chromium``)
loads the report written by ``safenav experiment``, every figure decodes
(naturalWidth > 0) and the console shows no errors.

Marked ``browser``: it runs only with ``-m browser`` or
``SAFENAV_BROWSER_TESTS=1`` (see conftest.py), and needs ``chromium``."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest

from safenav import cli

pytestmark = pytest.mark.browser

# Collected from the start of the page: console errors, uncaught exceptions and
# failed resource loads; at load, each image's size goes into a <pre id="probe">.
PROBE_HEAD = """<script>
window.__errors = [];
const __error = console.error.bind(console);
console.error = (...a) => { window.__errors.push(a.map(String).join(' ')); __error(...a); };
window.addEventListener('error', e => {
  window.__errors.push(e.message || ('failed to load ' + (e.target && (e.target.src || e.target.href))));
}, true);
window.addEventListener('load', () => {
  const imgs = Array.from(document.images).map(i => ({alt: i.alt, complete: i.complete, w: i.naturalWidth,
                                                    h: i.naturalHeight}));
  const pre = document.createElement('pre');
  pre.id = 'probe';
  pre.textContent = JSON.stringify({images: imgs, errors: window.__errors});
  document.body.appendChild(pre);
});
</script>"""


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("needs Debian's chromium (apt-get install chromium)")
    return exe


def test_report_renders_in_headless_chromium_with_every_figure_and_no_console_error(tmp_path):
    exe = _chromium()
    out = tmp_path / "exp"
    assert cli.main(["experiment", "field", "synthetic", "--trials", "2", "--particles", "50", "--camera-trials", "0",
                     "--out", str(out), "--quiet"]) == 0
    report = (out / "report.html").read_text(encoding="utf-8")
    n_figures = report.count("<img ")
    assert n_figures == 2
    probed = tmp_path / "probed.html"
    probed.write_text(report.replace("<head>", "<head>" + PROBE_HEAD, 1), encoding="utf-8")
    run = subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
         "--disable-background-networking", "--host-resolver-rules=MAP * ~NOTFOUND",   # no network
         f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=10000", "--dump-dom", probed.as_uri()],
        capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stderr[-2000:]
    m = re.search(r'<pre id="probe">(.*?)</pre>', run.stdout, re.S)
    assert m, "the page did not finish loading: " + run.stdout[-500:]
    probe = json.loads(m.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">")
                       .replace("&amp;", "&"))
    assert len(probe["images"]) == n_figures
    for img in probe["images"]:
        assert img["complete"] and img["w"] > 100 and img["h"] > 100, img
    assert probe["errors"] == []
    # Chromium's own log of the page's console (it logs console.error at INFO level): the report logs nothing
    assert [line for line in run.stderr.splitlines() if ":CONSOLE" in line] == []
