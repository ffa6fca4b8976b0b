"""The batch report in a real browser (headless Chromium driven by Selenium through
chromium-driver), its HTML through a strict HTML5 parser, and its colours against the
colour-science package.

    python scripts/report-browser.py GONIOSPEC_BINARY BATCH_DIR OUT_DIR

BATCH_DIR is a merged library with its report at BATCH_DIR/report/index.html. Prints
`name: value unit` figures and exits non-zero on the first failed check. A negative control
(the page with one image removed) proves the harness sees a missing image and a failed
request, so the image and request checks can fail.
"""

import csv
import io
import json
import os
import shutil
import subprocess
import sys
import time

import warnings

with warnings.catch_warnings():
    # colour-science names the optional packages it runs without (SciPy, Matplotlib).
    warnings.simplefilter("ignore")
    import colour
# It also says when it trims a 400-700 nm spectrum to its tables' shape: expected here.
warnings.filterwarnings("ignore", category=colour.utilities.ColourRuntimeWarning)
import html5lib
import numpy as np
from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

BIN, BATCH, OUT = sys.argv[1], os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3])
PAGE = os.path.join(BATCH, "report", "index.html")
os.makedirs(OUT, exist_ok=True)


def fail(msg):
    sys.exit(f"report-browser: FAILED: {msg}")


def browser():
    o = Options()
    for a in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1400,1200", "--allow-file-access-from-files"]:
        o.add_argument(a)
    o.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    o.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    return webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"),
                            options=o)


def load(driver, path):
    """Opens `path`; returns (console errors, failed requests, images as (src, naturalWidth))."""
    driver.get("file://" + path)
    t0 = time.monotonic()
    while driver.execute_script("return document.readyState") != "complete":
        if time.monotonic() - t0 > 30:
            fail(f"{path} did not finish loading in 30 s")
        time.sleep(0.05)
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    failed = []
    for e in driver.get_log("performance"):
        m = json.loads(e["message"])["message"]
        if m["method"] == "Network.loadingFailed":
            failed.append(m["params"].get("errorText", "?"))
        elif m["method"] == "Network.responseReceived":
            status = m["params"]["response"].get("status", 0)
            if status >= 400:
                failed.append(f"HTTP {status} {m['params']['response']['url']}")
    images = driver.execute_script(
        "return Array.from(document.images).map(i => [i.getAttribute('src'), i.naturalWidth]);")
    return errors, failed, images


def rows(driver, key):
    return [r.get_attribute("data-" + key) for r in driver.find_elements(By.CSS_SELECTOR, "#materials tr")]


# --- 1. The HTML: a strict HTML5 parse (any parse error raises) and a stated subset of
# conformance checks html5lib does not make.
html = open(PAGE, encoding="utf-8").read()
try:
    doc = html5lib.HTMLParser(strict=True, namespaceHTMLElements=False).parse(html)
except html5lib.html5parser.ParseError as e:
    fail(f"the page is not well-formed HTML5: {e}")
root = doc
if root.get("lang") != "en":
    fail("<html> has no lang")
if root.find(".//head/meta[@charset='utf-8']") is None or root.find(".//head/title") is None:
    fail("<head> lacks <meta charset> or <title>")
ids = [e.get("id") for e in root.iter() if e.get("id")]
if len(ids) != len(set(ids)):
    fail(f"duplicate ids: {ids}")
imgs = list(root.iter("img"))
if not imgs or any(not i.get("alt") for i in imgs):
    fail("an <img> without alt text")
for e in root.iter():
    for a in ("src", "href"):
        v = e.get(a)
        if v and (v.startswith("http:") or v.startswith("https:") or v.startswith("//")):
            fail(f"a remote resource: {v}")
for th in root.iter("th"):
    b = th.find("button")
    if b is not None and b.get("type") != "button":
        fail("a sort button without type=button")
print(f"html_strict_parse_errors: 0 count")
print(f"html_images_with_alt: {len(imgs)} count")

# --- 2. The page in Chromium.
driver = browser()
try:
    errors, failed, images = load(driver, PAGE)
    if errors:
        fail(f"console errors: {errors}")
    if failed:
        fail(f"failed requests: {failed}")
    if len(images) != len(imgs) or any(w <= 0 for _, w in images):
        fail(f"images that did not load: {[s for s, w in images if w <= 0]}")
    print(f"browser_console_errors: 0 count")
    print(f"browser_failed_requests: 0 count")
    print(f"browser_images_loaded: {len(images)} count")

    # Sorting: by reflectance (ascending, then descending on a second click), by name.
    header = lambda key: driver.find_element(By.CSS_SELECTOR, f"th button[data-key='{key}']")
    header("y").click()
    ys = [float(v) for v in rows(driver, "y")]
    if ys != sorted(ys):
        fail(f"sorting by reflectance gave {ys}")
    header("y").click()
    ys = [float(v) for v in rows(driver, "y")]
    if ys != sorted(ys, reverse=True):
        fail(f"sorting by reflectance again gave {ys}")
    header("name").click()
    names = rows(driver, "name")
    if names != sorted(names):
        fail(f"sorting by name gave {names}")
    sort = header("name").find_element(By.XPATH, "..").get_attribute("aria-sort")
    if sort != "ascending":
        fail(f"aria-sort after sorting by name is {sort}")
    errors, failed, _ = load(driver, PAGE)  # a reload clears the logs of the clicks above
    print(f"sorted_rows: {len(names)} count")

    # The screenshot: the whole page (Chrome DevTools Protocol, beyond the viewport).
    height = driver.execute_script("return document.documentElement.scrollHeight")
    driver.set_window_size(1400, min(int(height) + 40, 8000))
    shot = os.path.join(OUT, "report.png")
    driver.save_screenshot(shot)
    print(f"screenshot_bytes: {os.path.getsize(shot)} bytes")

    # Negative control: the same page with one image gone shows the failure.
    control = os.path.join(BATCH, "report-control")
    shutil.rmtree(control, ignore_errors=True)
    shutil.copytree(os.path.join(BATCH, "report"), control)
    gone = [f for f in sorted(os.listdir(control)) if f.endswith("-sphere.png")][0]
    os.remove(os.path.join(control, gone))
    errors, failed, images = load(driver, os.path.join(control, "index.html"))
    broken = [s for s, w in images if w <= 0]
    if broken != [gone] or not failed:
        fail(f"the control page (without {gone}) was not caught: broken {broken}, failed {failed}")
    print("negative_control_caught: 1 bool")
finally:
    driver.quit()

# --- 3. Colours: Y of each swatch against colour-science (CIE 1931 2-degree observer,
# illuminant D65, its own integration) from the CLI's reflectance CSV.
cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
d65 = colour.SDS_ILLUMINANTS["D65"]
worst = 0.0
manifest = open(os.path.join(BATCH, "manifest.toml"), encoding="utf-8").read()
names = sorted(set(rows_name for rows_name in
                   [l.split('"')[1] for l in manifest.splitlines() if l.startswith("name = ")]))
for name in names:
    gsa = os.path.join(BATCH, "out", f"{name}.gsa")
    start = html.index(f'data-name="{name}"')
    row = html[start:html.index("</tr>", start)]
    for cell in row.split('<div class="sw">')[1:]:
        theta = cell.split("&deg;")[0].split(">")[-1]
        shown = float(cell.split("Y ")[1].split("<")[0].rstrip("&dagger;"))
        out = subprocess.run([BIN, "reflectance", gsa, "--theta-i", theta], capture_output=True,
                             text=True, check=True).stdout
        data = list(csv.DictReader(io.StringIO(out)))
        lam = np.array([float(r["lambda_nm"]) for r in data])
        refl = np.array([float(r["R"]) for r in data])
        sd = colour.SpectralDistribution(dict(zip(lam, refl)), name=name)
        want = colour.sd_to_XYZ(sd, cmfs, d65)[1] / 100.0
        # The page treats R as constant over each bin; colour-science interpolates the same
        # samples. Within a bin the two reconstructions differ by at most half the step to
        # the neighbouring sample, so |dY| <= max |R[k+1] - R[k]| / 2 (weights sum to Y of a
        # white <= 1), plus the page's rounding to 3 decimals.
        bound = 0.5 * np.max(np.abs(np.diff(refl))) + 5e-4
        worst = max(worst, abs(shown - want))
        if abs(shown - want) > bound:
            fail(f"{name} at {theta} deg: page Y {shown}, colour-science {want:.4f} (bound {bound:.4f})")
print(f"colour_science_max_abs_y_difference: {worst:.2e} 1")
print("report-browser: ok")
