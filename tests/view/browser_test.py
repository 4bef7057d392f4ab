#!/usr/bin/python3
"""The viewer in a real browser: starts `incise view` on a scene (paused, on a free port), loads
the page in headless Chromium, checks that it draws the server's boundary, drags a blade across
the body with real mouse events, checks that the server's mesh gained cut faces and that the page
draws them, then lets the scene play and prints what was delivered (frames per second to the
page, bytes per frame, the server's frame and cut-step times; printed, not asserted).
Screenshots go to OUT_DIR.

usage: browser_test.py INCISE SCENE.json OUT_DIR
"""
import json
import os
import re
import subprocess
import sys
import threading
import time
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By


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


def main():
    incise, scene, out_dir = sys.argv[1:4]
    os.makedirs(out_dir, exist_ok=True)
    server = subprocess.Popen([incise, "view", scene, "--port", "0", "--paused"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    url = None
    lines = []

    def read_stdout():
        nonlocal url
        for line in server.stdout:
            lines.append(line)
            m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
            if m and url is None:
                url = m.group(1)

    threading.Thread(target=read_stdout, daemon=True).start()
    driver = None
    try:
        wait_for("the server's URL on stdout", lambda: url or (server.poll() is not None and fail(
            "incise view exited: " + server.stderr.read())), timeout=30)
        print("server:", url, flush=True)

        def status():
            with urllib.request.urlopen(url + "status", timeout=5) as r:
                return json.loads(r.read())

        opts = Options()
        opts.binary_location = "/usr/bin/chromium"
        for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1000,760",
                  "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox"):
            opts.add_argument(a)
        driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
        driver.set_page_load_timeout(30)
        driver.get(url)
        page = lambda: driver.execute_script("return window.inciseView || null")

        # The boundary is drawn: the page's triangle count is the server's.
        s0 = status()
        wait_for("the page to draw the boundary", lambda: (page() or {}).get("triangles") == s0["triangles"])
        drawn = driver.find_element(By.ID, "tri-count").get_attribute("textContent")
        if int(drawn) != s0["triangles"]:
            fail(f"page shows {drawn} triangles, server has {s0['triangles']}")
        if s0["cut_triangles"] != 0:
            fail("the paused scene has cut faces before any cut")
        print(f"drawn: {s0['triangles']} boundary triangles (server {s0['triangles']}), "
              f"{s0['tets']} tets, {s0['vertices']} vertices", flush=True)
        time.sleep(0.5)  # a rendered frame for the screenshot
        driver.save_screenshot(os.path.join(out_dir, "view_before.png"))

        # A blade dragged across the middle of the body with real mouse events.
        canvas = driver.find_element(By.TAG_NAME, "canvas")
        t0 = time.time()
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, -150, 10).click_and_hold()
        for _ in range(30):
            chain.move_by_offset(10, 0).pause(0.03)
        chain.release().perform()
        drag_s = time.time() - t0

        s1 = wait_for("cut faces on the server", lambda: (lambda s: s if s["cut_triangles"] > 0 else None)(status()))
        wait_for("the page to draw the cut faces",
                 lambda: (lambda p, s: p["cutTriangles"] == s["cut_triangles"] and p["triangles"] == s["triangles"])(
                     page(), status()))
        s1 = status()
        p1 = page()
        print(f"cut: {s1['cut_triangles']} cut triangles on the server and on the page; "
              f"{s1['tets']} tets (+{s1['tets'] - s0['tets']}); {s1['blade_steps']} blade steps in a {drag_s:.1f} s drag, "
              f"mean {s1['mean_blade_step_ms']:.2f} ms, max {s1['max_blade_step_ms']:.2f} ms; "
              f"page errors: {p1['errors']}", flush=True)
        if p1["errors"]:
            fail("the page got error frames: " + str(p1["errors"]))
        time.sleep(0.3)
        driver.save_screenshot(os.path.join(out_dir, "view_after_cut.png"))

        # Play: the scene runs live (its own blade enters at frame 5); measure what the page gets.
        driver.find_element(By.ID, "pause").click()
        m0, b0, t0 = p1["messages"], p1["bytes"], time.time()
        time.sleep(4.0)
        p2, s2 = page(), status()
        dt = time.time() - t0
        frames = p2["messages"] - m0
        if frames <= 0:
            fail("no frames delivered while playing")
        print(f"playing: {frames / dt:.1f} frames/s delivered to the page, "
              f"{(p2['bytes'] - b0) / frames / 1024:.1f} KiB/frame on the wire; server: {s2['frames_played']} frames, "
              f"mean {s2['mean_frame_ms']:.1f} ms, max {s2['max_frame_ms']:.1f} ms per frame; "
              f"now {s2['triangles']} triangles ({s2['cut_triangles']} cut), min dihedral {s2['min_dihedral']:.1f} deg, "
              f"{s2['below']} tets below {s2['below_deg']} deg", flush=True)
        # A second cut while the simulation runs (the deformed shape).
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, 10, -120).click_and_hold()
        for _ in range(20):
            chain.move_by_offset(0, 10).pause(0.03)
        chain.release().perform()
        time.sleep(1.0)
        s3 = status()
        wait_for("the page to catch up", lambda: (lambda p, s: p["triangles"] == s["triangles"])(page(), status()))
        print(f"cut while playing: {s3['blade_steps']} blade steps in all, mean {s3['mean_blade_step_ms']:.2f} ms; "
              f"{s3['cut_triangles']} cut triangles", flush=True)
        driver.save_screenshot(os.path.join(out_dir, "view_playing.png"))
        if server.poll() is not None:
            fail("incise view stopped: " + server.stderr.read())
        print("PASS: screenshots in", out_dir, flush=True)
    finally:
        if driver is not None:
            driver.quit()
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()


if __name__ == "__main__":
    main()
