"""What the browser tests share: failing with one line, and waiting for a condition."""
import sys
import time

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service


def fail(msg):
    print("FAIL:", msg, flush=True)
    sys.exit(1)


def wait_for(what, fn, timeout=20.0, every=0.1):
    end = time.time() + timeout
    while True:
        value = fn()
        if value:
            return value
        if time.time() > end:
            fail("timed out waiting for " + what)
        time.sleep(every)


def start_chromium():
    """Debian's Chromium, headless, software-rendered WebGL, through its chromedriver."""
    opts = Options()
    opts.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1000,760",
              "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox"):
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
    driver.set_page_load_timeout(30)
    return driver


# The page's canvas read back (the renderer keeps its drawing buffer) and measured in the page:
#  - box: the body's extent in page pixels (pixels away from the background colour), rows: for
#    each asked row, the body's leftmost and rightmost pixel on it (null: none);
#  - smooth: how much of the brightness change between neighbouring body pixels (rows, away
#    from the outline) comes in steps of 3 levels or more. Flat shading changes brightness only
#    at the facets' edges, in steps; smooth shading in gradients of a level or two per pixel
#    (the liver: about 0.4 smooth, 0.85 flat);
#  - counts of pixels in rects by class: tool (silver: bright and grey), yellow and blue (two
#    label colours of the look test), for the tools and the labels uncovered by the section.
_CANVAS_JS = """
const [rows, rects] = arguments;
const c = document.querySelector('#view canvas'), k = c.width / c.clientWidth;
const w = c.width, h = c.height;
const t = document.createElement('canvas'); t.width = w; t.height = h;
const g = t.getContext('2d'); g.drawImage(c, 0, 0);
const d = g.getImageData(0, 0, w, h).data;
const body = (i) => Math.abs(d[4 * i] - 27) + Math.abs(d[4 * i + 1] - 30) + Math.abs(d[4 * i + 2] - 35) > 24;
const lum = (i) => 0.3 * d[4 * i] + 0.59 * d[4 * i + 1] + 0.11 * d[4 * i + 2];
let x0 = w, y0 = h, x1 = -1, y1 = -1, total = 0, steps = 0;
for (let y = 0; y < h; ++y) for (let x = 0; x < w; ++x) {
  const i = y * w + x;
  if (!body(i)) continue;
  x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
  if (x >= 1 && x + 2 < w && body(i - 1) && body(i + 1) && body(i + 2)) {
    const dl = Math.abs(lum(i + 1) - lum(i));
    total += dl;
    if (dl >= 3) steps += dl;
  }
}
const span = (yc) => {
  const y = Math.round(yc * k);
  let a = -1, b = -1;
  for (let x = 0; x < w; ++x) if (body(y * w + x)) { if (a < 0) a = x; b = x; }
  return a < 0 ? null : [a / k, b / k];
};
const count = ([rx0, ry0, rx1, ry1]) => {
  const n = { tool: 0, yellow: 0, blue: 0 };
  for (let y = Math.max(0, Math.round(ry0 * k)); y < Math.min(h, Math.round(ry1 * k)); ++y)
    for (let x = Math.max(0, Math.round(rx0 * k)); x < Math.min(w, Math.round(rx1 * k)); ++x) {
      const i = 4 * (y * w + x), r = d[i], gg = d[i + 1], b = d[i + 2];
      if (Math.min(r, gg, b) > 150 && Math.max(r, gg, b) - Math.min(r, gg, b) < 35) n.tool++;
      if (r > 110 && gg > 80 && b < 0.6 * gg && r < 1.5 * gg) n.yellow++;
      if (b > r + 40 && b > gg) n.blue++;
    }
  return n;
};
return { box: x1 < 0 ? null : [x0 / k, y0 / k, (x1 + 1) / k, (y1 + 1) / k], smooth: total > 0 ? steps / total : null,
         rows: (rows || []).map(span), rects: (rects || []).map(count) };
"""


def measure_canvas(driver, rows=(), rects=()):
    """See _CANVAS_JS: {box, smooth, rows, rects}, in page pixels."""
    return driver.execute_script(_CANVAS_JS, list(rows), [list(r) for r in rects])


def rect_of(driver, element_id):
    """The element's box in page pixels: [left, top, right, bottom]; None when not displayed."""
    return driver.execute_script(
        "const e = document.getElementById(arguments[0]); if (!e || !e.offsetParent) return null;"
        "const r = e.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom];", element_id)


def overlap(a, b):
    return a is not None and b is not None and a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def incision_bend(vtu):
    """How far a frame's cut faces are from one plane: the area-weighted RMS of their centroids'
    distance to the best-fitting plane over their RMS spread along the plane (the smallest over
    the largest singular value), on the rest shape, from the frame's `cut_face_mask`. A straight
    blade sweep gives about 0.01 (the liver_cut sample), the browser test's arc drag about 0.12."""
    import meshio
    import numpy as np
    m = meshio.read(vtu)
    p = m.points - m.point_data["displacement"]
    tets = m.cells_dict["tetra"]
    mask = np.asarray(m.cell_data["cut_face_mask"][0]).astype(int)
    cs, ws = [], []
    for ti in np.nonzero(mask)[0]:
        for k in range(4):
            if mask[ti] >> k & 1:
                a, b, c = (p[tets[ti][j]] for j in range(4) if j != k)
                cs.append((a + b + c) / 3)
                ws.append(0.5 * np.linalg.norm(np.cross(b - a, c - a)))
    if len(cs) < 3:
        return 0.0
    cs, ws = np.array(cs), np.array(ws)
    d = (cs - (cs * ws[:, None]).sum(0) / ws.sum()) * np.sqrt(ws)[:, None]
    s = np.linalg.svd(d, compute_uv=False)
    return float(s[2] / s[0])
