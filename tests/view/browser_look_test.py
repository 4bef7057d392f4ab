#!/usr/bin/python3
"""Look mode in a real browser: `incise view MESH` and `incise view RUN_DIR` (docs/view.md).
Opens the mesh, checks the page draws the server's triangles (boundary plus the worst elements'
faces, in red) and switches to label colours; then simulates a small run (a few frames of the
beam scene), opens its directory, checks the drawn count, moves the time slider and checks that
the frame and the drawn positions change and the stats.csv curve is plotted. Bad arguments get a
one-line error and exit 1. Screenshots go to OUT_DIR.

usage: browser_look_test.py INCISE MESH SCENE.json OUT_DIR
"""
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import urllib.request

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

from browser_util import fail, start_chromium, wait_for


class Viewer:
    """`incise view ARG` on a free port; url once it printed it."""

    def __init__(self, incise, arg):
        self.proc = subprocess.Popen([incise, "view", arg, "--port", "0"], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.url = None
        threading.Thread(target=self._read, daemon=True).start()
        wait_for("the server's URL on stdout", lambda: self.url or (self.proc.poll() is not None and fail(
            "incise view exited: " + self.proc.stderr.read())), timeout=30)

    def _read(self):
        for line in self.proc.stdout:
            m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
            if m and self.url is None:
                self.url = m.group(1)

    def status(self):
        with urllib.request.urlopen(self.url + "status", timeout=5) as r:
            return json.loads(r.read())

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def main():
    incise, mesh, scene, out_dir = sys.argv[1:5]
    os.makedirs(out_dir, exist_ok=True)

    # Bad arguments: one line on stderr, exit 1, before any server starts.
    empty = os.path.join(out_dir, "not_a_run")
    os.makedirs(empty, exist_ok=True)
    for bad in (os.path.join(out_dir, "missing.msh"), empty):
        r = subprocess.run([incise, "view", bad, "--port", "0"], capture_output=True, text=True, timeout=30)
        if r.returncode != 1 or len(r.stderr.strip().splitlines()) != 1:
            fail(f"incise view {bad}: exit {r.returncode}, stderr {r.stderr!r}")
        print(f"bad argument {os.path.basename(bad)}: exit 1, {r.stderr.strip()}", flush=True)

    run_dir = os.path.join(out_dir, "run")
    shutil.rmtree(run_dir, ignore_errors=True)
    sim = subprocess.run([incise, "simulate", scene, "-o", run_dir, "--frames", "3"], capture_output=True, text=True,
                         timeout=120)
    if sim.returncode != 0:
        fail("incise simulate: " + sim.stderr)

    driver = start_chromium()
    page = lambda: driver.execute_script("return window.inciseView || null")
    viewer = None
    try:
        # A mesh: boundary and worst elements drawn, as many as the server says.
        viewer = Viewer(incise, mesh)
        s = viewer.status()
        driver.get(viewer.url)
        wait_for("the page to draw the mesh", lambda: (page() or {}).get("triangles") == s["triangles"])
        p = page()
        if p["mode"] != "look" or p["worstTriangles"] != 4 * len(s["worst"]) or not s["worst"]:
            fail(f"look mode: page {p}, server worst {s['worst']}")
        if len(s["labels"]) > 1:
            wait_for("label colours", lambda: viewer.status()["colour"] == 3)
        else:
            Select(driver.find_element(By.ID, "colour")).select_by_value("4")
            wait_for("boundary-tag colours", lambda: viewer.status()["colour"] == 4)
        print(f"look {os.path.basename(mesh)}: {s['triangles']} triangles drawn (server {s['triangles']}), "
              f"{p['worstTriangles']} of them the {len(s['worst'])} worst elements' faces ({s['worst_from']}); "
              f"labels {s['labels']}; min dihedral {s['min_dihedral']:.2f} deg", flush=True)
        time.sleep(0.5)
        driver.save_screenshot(os.path.join(out_dir, "look_mesh.png"))
        viewer.stop()

        # A run directory: the slider changes the frame and the drawn positions; the curve is there.
        viewer = Viewer(incise, run_dir)
        s = viewer.status()
        driver.get(viewer.url)
        wait_for("the page to draw frame 0", lambda: (page() or {}).get("triangles") == s["triangles"] and
                 page()["frame"] == 0)
        if s["frames"] < 2:
            fail(f"the run lists {s['frames']} frames")
        wait_for("the stats.csv curve", lambda: driver.execute_script(
            "return document.querySelectorAll('#plot polyline').length") == 1)
        sum0 = page()["positionSum"]
        last = s["frames"] - 1
        driver.execute_script(f"const e = document.getElementById('frame'); e.value = '{last}'; "
                              "e.dispatchEvent(new Event('input'));")
        wait_for("the last frame", lambda: viewer.status()["frame"] == last and page()["frame"] == last)
        s1, p1 = viewer.status(), page()
        if p1["triangles"] != s1["triangles"] or abs(p1["positionSum"] - sum0) <= 1e-6 * max(1.0, abs(sum0)):
            fail(f"slider: page {p1}, server {s1}, position sum {sum0} -> {p1['positionSum']}")
        if p1["errors"]:
            fail("the page got error frames: " + str(p1["errors"]))
        print(f"run ({s['frames']} frames): {s1['triangles']} triangles drawn (server {s1['triangles']}); slider "
              f"0 -> {last}: t {s['time']} -> {s1['time']}, sum of drawn coordinates {sum0:.4f} -> "
              f"{p1['positionSum']:.4f}; curve of {len(s['stats']['rows'])} stats.csv rows", flush=True)
        time.sleep(0.5)
        driver.save_screenshot(os.path.join(out_dir, "look_run.png"))
        print("PASS: screenshots in", out_dir, flush=True)
    finally:
        driver.quit()
        if viewer is not None:
            viewer.stop()


if __name__ == "__main__":
    main()
