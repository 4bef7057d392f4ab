#!/usr/bin/python3
"""Look mode in a real browser: `incise view MESH` and `incise view RUN_DIR` (docs/view.md).
Opens the mesh, checks the page draws the server's triangles (boundary plus the worst elements'
faces, in magenta) and switches to label colours (with the faces between labels, and a legend of
the labels' colours); the section plane uncovers the labels the first view hides (on the canvas's
pixels); the colour bar of element quality and the legend of boundary tags; a refused input's
error in its banner, clear of the help text, dismissed. Then simulates a small run (a few frames of the beam
scene), opens its directory, checks the drawn count, moves the time slider and checks that the
frame and the drawn positions change and the stats.csv curve is plotted. Bad arguments get a
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

from browser_util import fail, measure_canvas, overlap, rect_of, start_chromium, wait_for


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


def faces_between_labels(msh):
    """A gmsh 2.2 ASCII mesh's faces shared by two tets of different labels (their first tag):
    the count the server's look mode draws while colouring by label, found independently."""
    with open(msh) as f:
        lines = f.read().split("\n")
    at = lines.index("$Elements")
    owners = {}
    for line in lines[at + 2:at + 2 + int(lines[at + 1])]:
        e = line.split()
        if e[1] != "4":
            continue
        ntags = int(e[2])
        label, v = int(e[3]), e[3 + ntags:]
        for skip in range(4):
            face = tuple(sorted(v[k] for k in range(4) if k != skip))
            owners.setdefault(face, []).append(label)
    return sum(1 for o in owners.values() if len(o) == 2 and o[0] != o[1])


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
        driver.get(viewer.url)
        labelled = len(viewer.status()["labels"]) > 1
        # Several labels: the page asks for label colours at once, and the server adds the faces
        # between labels to what it draws.
        if labelled:
            wait_for("label colours", lambda: viewer.status()["colour"] == 3)
        wait_for("the page to draw the mesh", lambda: (page() or {}).get("triangles") == viewer.status()["triangles"]
                 and (page() or {}).get("legend") is not None or not labelled)
        s, p = viewer.status(), page()
        if p["mode"] != "look" or p["worstTriangles"] != 4 * len(s["worst"]) or not s["worst"] or \
                p["triangles"] != s["triangles"] or p["interfaceTriangles"] != s["interfaces"]:
            fail(f"look mode: page {p}, server {s['triangles']} triangles, {s['interfaces']} between labels, "
                 f"worst {s['worst']}")
        print(f"look {os.path.basename(mesh)}: {s['triangles']} triangles drawn (server {s['triangles']}), "
              f"{p['worstTriangles']} of them the {len(s['worst'])} worst elements' faces ({s['worst_from']}), "
              f"{p['interfaceTriangles']} between labels (the file: {faces_between_labels(mesh) if mesh.endswith('.msh') else '-'}); "
              f"labels {s['labels']}; min dihedral "
              f"{s['min_dihedral']:.2f} deg", flush=True)
        time.sleep(0.5)
        driver.save_screenshot(os.path.join(out_dir, "look_mesh.png"))
        if labelled:
            # The legend: each label's colour, all distinct and none the worst elements' (magenta)
            # or the old worst red; the worst elements listed last.
            legend = p["legend"]
            colours = [i["colour"] for i in legend["items"]]
            if legend["kind"] != "category" or len(colours) != len(s["labels"]) + 1 or \
                    len(set(colours)) != len(colours) or colours[-1] != 0xff00ff or 0xff3030 in colours:
                fail(f"label legend: {legend}")
            expected = faces_between_labels(mesh) if mesh.endswith(".msh") else None
            if s["interfaces"] <= 0 or (expected is not None and s["interfaces"] != expected):
                fail(f"faces between labels: the server draws {s['interfaces']}, the mesh has {expected}")
            # The section plane uncovers what the first view hides: the smaller labels' colours
            # (yellow and blue, the second and third largest; on the liver they meet the boundary
            # only on the far side, and 255 in the faces between labels) appear only with it.
            whole = [0, 0, 10000, 10000]
            hidden = measure_canvas(driver, rects=[whole])["rects"][0]
            driver.execute_script("const e = document.getElementById('section'); e.value = '0.5'; "
                                  "e.dispatchEvent(new Event('input'));")
            wait_for("the section", lambda: page()["section"] == 0.5)
            time.sleep(0.5)
            shown = measure_canvas(driver, rects=[whole])["rects"][0]
            driver.save_screenshot(os.path.join(out_dir, "look_section.png"))
            print(f"section 0.5: the smaller labels' pixels (yellow, blue) {hidden['yellow']}, {hidden['blue']} -> "
                  f"{shown['yellow']}, {shown['blue']}; legend {[i['name'] for i in legend['items']]}", flush=True)
            if hidden["yellow"] + hidden["blue"] > 30 or shown["yellow"] + shown["blue"] < 300:
                fail(f"the section does not uncover the hidden labels: {hidden} -> {shown}")
            driver.execute_script("const e = document.getElementById('section'); e.value = '0'; "
                                  "e.dispatchEvent(new Event('input'));")

        # Element quality: the colour bar with the server's smallest and largest angle.
        Select(driver.find_element(By.ID, "colour")).select_by_value("2")
        wait_for("quality colours", lambda: viewer.status()["colour"] == 2)
        legend = wait_for("the colour bar", lambda: (page()["legend"] or {}).get("kind") == "scale" and page()["legend"])
        st, text = viewer.status(), driver.find_element(By.ID, "legend").text
        if not legend["title"].startswith("min dihedral") or legend["lo"] not in text or legend["hi"] not in text or \
                abs(float(legend["lo"]) - st["scalar_lo"]) > 0.006 * st["scalar_lo"] or \
                abs(float(legend["hi"]) - st["scalar_hi"]) > 0.006 * st["scalar_hi"]:
            fail(f"quality colour bar: {legend}, shown {text!r}, server {st['scalar_lo']} .. {st['scalar_hi']}")
        time.sleep(0.3)
        driver.save_screenshot(os.path.join(out_dir, "look_quality.png"))
        # Boundary tags: a legend of the tags.
        Select(driver.find_element(By.ID, "colour")).select_by_value("4")
        legend = wait_for("the tag legend", lambda: (page()["legend"] or {}).get("title") == "boundary tag" and
                          page()["legend"])
        print(f"colour bar (quality): {text!r}; tag legend {[i['name'] for i in legend['items']]}".replace("\n", " / "),
              flush=True)

        # A refused input (von Mises: this mesh has no stresses) gets its error in the banner,
        # which covers neither the help text nor the legend, and is dismissed by its button.
        driver.execute_script("const c = document.getElementById('colour'); c.add(new Option('x', '1')); c.value = '1'; "
                              "c.dispatchEvent(new Event('change'));")
        wait_for("the error banner", lambda: rect_of(driver, "error") is not None)
        banner = driver.find_element(By.ID, "error-text").text
        boxes = {k: rect_of(driver, k) for k in ("error", "help", "legend", "overlay")}
        driver.save_screenshot(os.path.join(out_dir, "look_error.png"))
        if "von Mises" not in banner or page()["errors"] != [banner] or any(
                overlap(boxes["error"], boxes[k]) for k in ("help", "legend", "overlay")):
            fail(f"the error banner: {banner!r}, page errors {page()['errors']}, boxes {boxes}")
        driver.find_element(By.ID, "error-close").click()
        wait_for("the banner dismissed", lambda: rect_of(driver, "error") is None)
        print(f"error banner: {banner!r}, clear of the help text, dismissed", flush=True)
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
