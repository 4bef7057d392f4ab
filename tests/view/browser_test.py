#!/usr/bin/python3
"""The viewer in a real browser: starts `incise view` on a scene (paused, on a free port), loads
the page in headless Chromium, checks that it draws the server's boundary, drags a blade across
the body with real mouse events, checks that the server's mesh gained cut faces and that the page
draws them, then lets the scene play and prints what was delivered (frames per second to the
page, bytes per frame, the server's frame and cut-step times; printed, not asserted).
Screenshots go to OUT_DIR.

usage: browser_test.py INCISE SCENE.json OUT_DIR [incise view options...]
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import urllib.request

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select

from browser_util import fail, start_chromium, wait_for


def main():
    incise, scene, out_dir = sys.argv[1:4]
    os.makedirs(out_dir, exist_ok=True)
    takes = os.path.join(out_dir, "takes")
    shutil.rmtree(takes, ignore_errors=True)
    server = subprocess.Popen([incise, "view", scene, "--port", "0", "--paused", "--record", takes] + sys.argv[4:],
                              stdout=subprocess.PIPE,
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

        driver = start_chromium()
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

        canvas = driver.find_element(By.TAG_NAME, "canvas")
        pause = driver.find_element(By.ID, "pause")

        def drag(x0, y0, dx, dy, steps):
            chain = ActionChains(driver, duration=20)
            chain.move_to_element_with_offset(canvas, x0, y0).click_and_hold()
            for _ in range(steps):
                chain.move_by_offset(dx, dy).pause(0.03)
            chain.release().perform()

        def set_paused(want):
            if status()["paused"] != want:
                pause.click()
            wait_for("pause" if want else "play", lambda: status()["paused"] == want)

        def synced():  # the page shows the server's newest frame
            p, s = page(), status()
            return p["frame"] == s["frame"] and p["triangles"] == s["triangles"] and \
                p["cutTriangles"] == s["cut_triangles"]

        def measure(what, seconds, during=None):
            p0, s0, t0 = page(), status(), time.time()
            if during:
                during()
            time.sleep(max(0.0, seconds - (time.time() - t0)))
            p1, s1, dt = page(), status(), time.time() - t0
            frames = p1["messages"] - p0["messages"]
            played = s1["frames_played"] - s0["frames_played"]
            if frames <= 0 or played <= 0:
                fail(what + ": no frames played or delivered")
            print(f"{what}: {frames / dt:.1f} frames/s delivered to the page "
                  f"({played / dt:.1f} played by the server), {(p1['bytes'] - p0['bytes']) / frames / 1024:.1f} KiB/frame "
                  f"on the wire; server frames mean {s1['mean_frame_ms']:.1f} ms, max {s1['max_frame_ms']:.1f} ms "
                  f"(all so far); {s1['tets']} tets, {s1['cut_triangles']} cut triangles, min dihedral "
                  f"{s1['min_dihedral']:.2f} deg, {s1['below']} tets below {s1['below_deg']} deg", flush=True)

        # Play the scene (it sags under gravity) and measure what the page gets.
        set_paused(False)
        wait_for("the first frames (the first solve factors K)", lambda: status()["frames_played"] >= 3, timeout=30)
        measure("playing, uncut", 2.0)

        # Paused, a blade dragged across the middle of the body with real mouse events: the
        # server's mesh gains cut faces and the page draws them.
        set_paused(True)
        wait_for("the page to catch up", synced)
        c0 = status()["cut_triangles"]
        t0 = time.time()
        drag(-150, 10, 10, 0, 30)
        drag_s = time.time() - t0
        wait_for("cut faces on the server", lambda: status()["cut_triangles"] > c0)
        wait_for("the page to draw the cut faces", synced)
        s1, p1 = status(), page()
        print(f"cut (paused): {s1['cut_triangles'] - c0} new cut triangles on the server, the page draws "
              f"{p1['cutTriangles']} of {s1['cut_triangles']}; {s1['tets']} tets; {s1['blade_steps']} blade steps "
              f"in a {drag_s:.1f} s drag, mean {s1['mean_blade_step_ms']:.2f} ms, max "
              f"{s1['max_blade_step_ms']:.2f} ms", flush=True)
        if p1["errors"]:
            fail("the page got error frames: " + str(p1["errors"]))
        time.sleep(0.3)
        driver.save_screenshot(os.path.join(out_dir, "view_after_cut.png"))

        # The clip view: the tets below 10 deg drawn whole, in red over the body; off again at 0.
        def set_clip(deg):
            driver.execute_script("const c = document.getElementById('clip'); c.value = arguments[0]; "
                                  "c.dispatchEvent(new Event('change'));", str(deg))
            wait_for(f"clip {deg}", lambda: status()["clip_deg"] == deg)
            wait_for("the page to draw the clip", synced)
        set_clip(10)
        sc = status()
        if sc["clip_tets"] != min(sc["below"], sc["clip_max"]) or page()["worstTriangles"] != 4 * sc["clip_tets"]:
            fail(f"clip 10: server {sc['clip_tets']} tets ({sc['below']} below 10 deg), the page draws "
                 f"{page()['worstTriangles']} red triangles")
        time.sleep(0.3)
        driver.save_screenshot(os.path.join(out_dir, "view_clip.png"))
        print(f"clip: {sc['clip_tets']} tets below 10 deg drawn ({page()['worstTriangles']} triangles)", flush=True)
        set_clip(0)
        if page()["worstTriangles"] != 0:
            fail("clip 0 still draws tets")

        # Cutting while the scene plays (the blade cuts the deformed shape).
        set_paused(False)
        measure("playing, cutting", 4.0, during=lambda: drag(10, -120, 0, 10, 24))
        time.sleep(0.5)
        driver.save_screenshot(os.path.join(out_dir, "view_playing.png"))
        # Probe (Shift+drag), colour by stress, then a reset: no error frames, the page follows.
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, 60, 40).key_down(Keys.SHIFT).click_and_hold()
        for _ in range(8):
            chain.move_by_offset(0, -6).pause(0.03)
        chain.release().key_up(Keys.SHIFT).perform()
        Select(driver.find_element(By.ID, "colour")).select_by_value("1")
        wait_for("von Mises colours", lambda: status()["colour"] == 1)
        time.sleep(0.8)
        driver.save_screenshot(os.path.join(out_dir, "view_stress.png"))
        if page()["errors"]:
            fail("the page got error frames: " + str(page()["errors"]))
        # A blade through the whole depth, dragged across the body from edge to edge, detaches
        # the far part; the scene's fragment policy (static FEM: remove) takes it away.
        set_paused(True)
        sb = status()
        driver.execute_script("document.getElementById('depth').value = '1'")
        drag(-60, -220, 0, 10, 44)
        time.sleep(1.0)
        wait_for("the page to catch up", synced)
        sa = status()
        print(f"through-cut: fragments handled {sb['fragments_handled']} -> {sa['fragments_handled']}, "
              f"{sb['tets']} -> {sa['tets']} tets, {sb['triangles']} -> {sa['triangles']} triangles, "
              f"{sa['blade_steps'] - sb['blade_steps']} blade steps, page errors {page()['errors']}", flush=True)
        # The blade stays on the mouse's ray, so past the outline it has left the body: the part
        # away from the fixed side is cut off and removed (with the earlier cuts, sometimes as
        # more than one piece). Before, a blade that only translated lagged behind the ray at
        # depth and detached nothing.
        if sa["fragments_handled"] <= sb["fragments_handled"] or sa["tets"] >= sb["tets"] or page()["errors"]:
            fail("the through-cut detached nothing")
        driver.save_screenshot(os.path.join(out_dir, "view_through_cut.png"))
        driver.find_element(By.ID, "reset").click()
        wait_for("the reset", lambda: status()["cut_triangles"] == 0 and status()["tets"] == s0["tets"])
        wait_for("the page to draw the reset body", lambda: page()["cutTriangles"] == 0 and
                 page()["triangles"] == s0["triangles"])
        print("probe, colour and reset: no error frames; after the reset the page draws "
              f"{page()['triangles']} triangles again", flush=True)

        # Record: a take of a cut (paused, from the reset's start) and two frames; `incise simulate`
        # replays its scene.json to the same cut mesh.
        set_paused(True)
        record = driver.find_element(By.ID, "record")
        record.click()
        wait_for("recording", lambda: status()["recording"] == "take-1")
        # A curved drag (an arc on the screen): the blade follows the drag's own path.
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, -150, 10).click_and_hold()
        for k in range(30):
            chain.move_by_offset(10, round(4 * math.cos(math.pi * (k + 0.5) / 30))).pause(0.03)
        chain.release().perform()
        wait_for("cut faces on the server", lambda: status()["cut_triangles"] > 0)
        for k in range(2):
            f = status()["frame"]
            driver.find_element(By.ID, "step").click()
            wait_for("a step", lambda: status()["frame"] == f + 1)
        record.click()
        wait_for("the take written", lambda: status()["recording"] == "" and status()["last_take"] != "")
        st = status()
        take = st["last_take"]
        for f in ["scene.json", "frames.pvd", "stats.csv", "frame_0000.vtu", "frame_0001.vtu"]:
            if not os.path.exists(os.path.join(take, f)):
                fail(f"the take has no {f}: {sorted(os.listdir(take))}")
        with open(os.path.join(take, "scene.json")) as fh:
            inputs = json.load(fh)["inputs"]
        blades = sum(1 for i in inputs if "blade" in i)
        # The recorded blade path is the drag's: its near end bends step after step (the server
        # once straightened drags onto lines, which left the middle of nearly every triple of
        # consecutive positions exactly on the line through its neighbours).
        near = [i["blade"][0] for i in inputs if "blade" in i]
        bent = 0
        for p, x, q in zip(near, near[1:], near[2:]):
            d = [q[k] - p[k] for k in range(3)]
            r = [x[k] - p[k] for k in range(3)]
            cross = [r[1] * d[2] - r[2] * d[1], r[2] * d[0] - r[0] * d[2], r[0] * d[1] - r[1] * d[0]]
            if math.sqrt(sum(c * c for c in cross)) > 1e-6 * math.sqrt(sum(c * c for c in d)) ** 2:
                bent += 1
        if len(near) < 10 or bent < (len(near) - 2) // 2:
            fail(f"the take's blade path is straightened: {bent} of {len(near) - 2} positions off their neighbours' line")
        replay = os.path.join(out_dir, "replay")
        shutil.rmtree(replay, ignore_errors=True)
        r = subprocess.run([incise, "simulate", os.path.join(take, "scene.json"), "-o", replay], capture_output=True,
                           text=True, timeout=120)
        if r.returncode != 0:
            fail("incise simulate on the take: " + r.stderr)
        m = re.search(r"(\d+) tets", r.stdout + r.stderr)
        replay_tets = int(m.group(1)) if m else -1
        print(f"record: {take} with {len(inputs)} inputs ({blades} blade steps), 2 frames; the replay has "
              f"{replay_tets} tets, the live session {st['tets']}", flush=True)
        if replay_tets != st["tets"]:
            fail(f"the replay of the take has {replay_tets} tets, the live session had {st['tets']}: "
                 + r.stdout[-500:])

        # Security: bad inputs get an error frame and change nothing; other origins are refused.
        set_paused(True)  # so that the scene's own blade changes nothing either
        before = status()
        replies = driver.execute_async_script("""
            const done = arguments[arguments.length - 1];
            const ws = new WebSocket(`ws://${location.host}/ws`);
            ws.binaryType = 'arraybuffer';
            const errors = [];
            ws.onmessage = (e) => { if (typeof e.data === 'string') errors.push(JSON.parse(e.data).error); };
            ws.onopen = () => {
              ws.send(new Uint8Array([99]));                 // unknown kind
              ws.send(new Uint8Array([2, 0, 0]));            // a blade move cut short
              ws.send('pause');                              // text is not an input
              const far = new DataView(new ArrayBuffer(25)); far.setUint8(0, 1);
              for (let i = 0; i < 6; ++i) far.setFloat32(1 + 4 * i, 1e9 * (i % 2 ? 1 : -1), true);
              ws.send(far.buffer);                           // a blade far outside the body
              setTimeout(() => { ws.close(); done(errors); }, 1000);
            };
            ws.onerror = () => done(['socket failed']);""")
        after = status()
        if len(replies) != 4 or after["tets"] != before["tets"] or after["blade_steps"] != before["blade_steps"] or \
                after["paused"] != before["paused"]:
            fail(f"bad inputs: replies {replies}, status before {before}, after {after}")
        import http.client
        host = url.split("/")[2]
        conn = http.client.HTTPConnection(host, timeout=5)
        conn.request("GET", "/ws", headers={"Connection": "Upgrade", "Upgrade": "websocket",
                                            "Sec-WebSocket-Version": "13", "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
                                            "Origin": "http://evil.example"})
        other_origin = conn.getresponse().status
        conn = http.client.HTTPConnection(host, timeout=5)
        conn.request("GET", "/../../etc/passwd")
        outside = conn.getresponse().status
        if other_origin != 403 or outside != 404:
            fail(f"another origin got {other_origin}, a path outside the page {outside}")
        print(f"security: 4 bad inputs, 4 error frames ({'; '.join(replies)}), nothing changed; "
              f"another origin {other_origin}, a file outside the page {outside}", flush=True)

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
