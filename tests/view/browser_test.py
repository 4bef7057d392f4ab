#!/usr/bin/python3
"""The viewer in a real browser: starts `incise view` on a scene (paused, on a free port), loads
the page in headless Chromium, checks that it draws the server's boundary smooth-shaded (on the
canvas's pixels, against the same view in facets), that a drag entirely beside the body cuts
nothing and says "no cut", drags a blade from beside the body across it with real mouse events
(the blade and its path drawn while it moves), checks that the server's mesh gained cut faces and
that the page draws them, then lets the scene play and prints what was delivered (frames per
second to the page, bytes per frame, the server's frame and cut-step times; printed, not
asserted); the colour bar of the stress and quality colourings; the probe drawn while it drags.
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

from browser_util import fail, incision_bend, measure_canvas, overlap, rect_of, start_chromium, wait_for


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

        # Smooth shading: per-vertex normals (split at creases and cut rims), and on the pixels,
        # brightness changing in gradients across the organ, not in steps at the facets' edges
        # as the same view drawn in facets (flat shading) does.
        p = page()
        smooth = measure_canvas(driver)
        driver.find_element(By.ID, "facets").click()
        wait_for("facets", lambda: page()["normals"] == "face")
        time.sleep(0.4)
        flat = measure_canvas(driver)
        driver.save_screenshot(os.path.join(out_dir, "view_facets.png"))
        driver.find_element(By.ID, "facets").click()
        wait_for("smooth again", lambda: page()["normals"] == "vertex")
        print(f"shading: per-vertex normals, {p['splitVertices']} vertices split at creases; brightness in steps "
              f"of 3+ levels: {smooth['smooth']:.2f} of the change smooth, {flat['smooth']:.2f} in facets", flush=True)
        if p["normals"] != "vertex" or p["splitVertices"] <= 0 or not smooth["smooth"] or \
                smooth["smooth"] > 0.6 or smooth["smooth"] > 0.7 * flat["smooth"]:
            fail(f"not smooth-shaded: page {p['normals']} normals, steps {smooth['smooth']} (facets {flat['smooth']})")
        box = smooth["box"]  # the body on the page: [left, top, right, bottom]

        canvas = driver.find_element(By.TAG_NAME, "canvas")
        pause = driver.find_element(By.ID, "pause")
        size = driver.execute_script("const c = document.querySelector('#view canvas'); return [c.clientWidth, c.clientHeight];")

        def at(x, y):  # page pixels -> offsets from the canvas's centre (Selenium's origin)
            return round(x - size[0] / 2), round(y - size[1] / 2)

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

        # Paused, a drag entirely beside the body (left of it, moving away): the blade meets
        # nothing, the page flashes "no cut" and the server's mesh is unchanged.
        set_paused(True)
        wait_for("the page to catch up", synced)
        sn, pn = status(), page()
        x, y = max(20, box[0] - 150), box[3] - 30
        drag(*at(x, y), -8, 4, 10)
        wait_for("the no-cut flash", lambda: page()["noCut"] == pn["noCut"] + 1)
        flash = driver.execute_script("const f = document.getElementById('flash'); "
                                      "return [f.textContent, f.classList.contains('on')];")
        time.sleep(0.3)
        sa = status()
        if page()["lastPress"]["hit"] or sa["tets"] != sn["tets"] or sa["cut_triangles"] != sn["cut_triangles"] or \
                sa["blade_drags"] != sn["blade_drags"] + 1 or sa["drag_tets_cut"] != 0 or \
                flash != ["no cut: the blade did not meet the body", True]:
            fail(f"a drag beside the body: flash {flash}, press {page()['lastPress']}, server {sn['tets']} -> "
                 f"{sa['tets']} tets, drag_tets_cut {sa['drag_tets_cut']}")
        driver.save_screenshot(os.path.join(out_dir, "view_no_cut.png"))
        print(f"a drag beside the body, away from it: \"{flash[0]}\" flashed, {sa['tets']} tets unchanged", flush=True)

        # Paused, a blade dragged across the middle of the body with real mouse events: drawn
        # while it moves (its path in silver, its ends on the pointer's ray), the server's mesh
        # gains cut faces and the page draws them.
        c0 = status()["cut_triangles"]
        x0, ym = size[0] / 2 - 150, size[1] / 2 + 10
        path = [x0 + 20, ym - 8, x0 + 200, ym + 8]  # the stretch the path covers by mid-drag
        before = measure_canvas(driver, rects=[path])["rects"][0]["tool"]
        t0 = time.time()
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, *at(x0, ym)).click_and_hold()
        for _ in range(22):
            chain.move_by_offset(10, 0).pause(0.03)
        chain.perform()
        time.sleep(0.3)  # a rendered frame
        mid, blade = measure_canvas(driver, rects=[path])["rects"][0]["tool"], page()["blade"]
        driver.save_screenshot(os.path.join(out_dir, "view_blade.png"))
        chain = ActionChains(driver, duration=20)
        for _ in range(8):
            chain.move_by_offset(10, 0).pause(0.03)
        chain.release().perform()
        drag_s = time.time() - t0
        press = page()["lastPress"]
        print(f"blade drawn mid-drag: {mid} silver pixels along its path ({before} before), ends on screen at "
              f"{[[round(c) for c in e] for e in (blade or {}).get('screen', [])]}, pointer at "
              f"({x0 + 220:.0f}, {ym:.0f})", flush=True)
        if not blade or mid < 300 or before > 20 or page()["blade"] is not None or not press["hit"] or \
                any(math.hypot(e[0] - (x0 + 220), e[1] - ym) > 3 for e in blade["screen"]):
            fail(f"the blade while dragging: {blade}, silver pixels {before} -> {mid}, press {press}, "
                 f"after release {page()['blade']}")
        wait_for("cut faces on the server", lambda: status()["cut_triangles"] > c0)
        wait_for("the page to draw the cut faces", synced)
        wait_for("the drag's figures", lambda: page()["lastDragTetsCut"] is not None)
        s1, p1 = status(), page()
        # A cut's rim splits its vertices' normals (the cut faces are not smoothed into the skin).
        if p1["lastDragTetsCut"] <= 0 or p1["noCut"] != pn["noCut"] + 1 or p1["splitVertices"] <= p["splitVertices"]:
            fail(f"the drag: {p1['lastDragTetsCut']} tets cut, no-cut flashes {pn['noCut']} -> {p1['noCut']}, "
                 f"split vertices {p['splitVertices']} -> {p1['splitVertices']}")
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
        # Probe (Shift+drag; drawn at the grabbed point as it moves), colour by stress, then a
        # reset: no error frames, the page follows.
        chain = ActionChains(driver, duration=20)
        chain.move_to_element_with_offset(canvas, 60, 40).key_down(Keys.SHIFT).click_and_hold()
        for _ in range(8):
            chain.move_by_offset(0, -6).pause(0.03)
        chain.perform()
        time.sleep(0.2)  # the last move is sent (and drawn) on the next animation frame
        probe = page()["probe"]
        ActionChains(driver, duration=20).release().key_up(Keys.SHIFT).perform()
        px, py = size[0] / 2 + 60, size[1] / 2 + 40 - 48
        if not probe or math.hypot(probe["screen"][0] - px, probe["screen"][1] - py) > 3 or page()["probe"] is not None:
            fail(f"the probe while dragging: {probe} (pointer at {px}, {py}), after release {page()['probe']}")

        # The colour bar: shown for the scalar colourings with the scale's ends (the server's),
        # beside the help and the overlay, not over them; none for plain colours.
        def colour_bar(value, title):
            Select(driver.find_element(By.ID, "colour")).select_by_value(value)
            wait_for(title + " colours", lambda: status()["colour"] == int(value) and status()["frame"] == page()["frame"])
            st = status()
            legend = wait_for("the colour bar", lambda: (page()["legend"] or {}).get("title", "").startswith(title)
                              and page()["legend"])
            text = driver.find_element(By.ID, "legend").text
            lo, hi = float(legend["lo"]), float(legend["hi"])
            close = lambda a, b: abs(a - b) <= 0.006 * max(abs(a), abs(b)) + 1e-12
            if legend["kind"] != "scale" or legend["lo"] not in text or legend["hi"] not in text or \
                    not close(lo, st["scalar_lo"]) or not close(hi, st["scalar_hi"]) or \
                    overlap(rect_of(driver, "legend"), rect_of(driver, "help")) or \
                    overlap(rect_of(driver, "legend"), rect_of(driver, "overlay")):
                fail(f"colour bar of {title}: {legend}, shown {text!r}, server {st['scalar_lo']} .. {st['scalar_hi']}")
            print(f"colour bar: {text!r} (server {st['scalar_lo']:.4g} .. {st['scalar_hi']:.4g})".replace("\n", " / "),
                  flush=True)

        set_paused(True)
        colour_bar("1", "von Mises")
        time.sleep(0.3)
        driver.save_screenshot(os.path.join(out_dir, "view_stress.png"))
        colour_bar("2", "min dihedral")
        driver.save_screenshot(os.path.join(out_dir, "view_quality.png"))
        Select(driver.find_element(By.ID, "colour")).select_by_value("0")
        wait_for("plain colours, no colour bar", lambda: status()["colour"] == 0 and page()["legend"] is None and
                 rect_of(driver, "legend") is None)
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
        # ... and so is the incision: its cut faces bend away from any one plane (a straight
        # sweep's stay within about 0.01 of their extent, the liver_cut sample's; this arc ~0.12).
        bend = incision_bend(os.path.join(take, "frame_0001.vtu"))
        if bend < 0.05:
            fail(f"the curved drag's incision is flat: its cut faces within {bend:.3f} of one plane")
        print(f"curved drag: the incision bends {bend:.3f} off one plane (a straight sweep: about 0.01)", flush=True)
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

        # A drag started beside the body (left of its outline, on a row the cuts so far have not
        # touched), moved across it, shallow: the press's ray misses the body, so the blade goes
        # to the depth where the ray passes nearest to it, and the drag cuts. (Before, such a
        # blade reached half the body's size in front of its centre plus the depth: at 0.15 it
        # stopped in front of the liver and the drag cut nothing.)
        set_paused(True)
        wait_for("the page to catch up", synced)
        driver.execute_script("document.getElementById('depth').value = '0.15'")
        sb, pb = status(), page()
        box = measure_canvas(driver)["box"]
        yb = box[1] + 0.75 * (box[3] - box[1])
        left = measure_canvas(driver, rows=[yb])["rows"][0][0]
        drag(*at(left - 30, yb), 10, 0, 22)
        wait_for("the drag's figures", lambda: page()["lastDragTetsCut"] is not None)
        wait_for("the page to catch up", synced)
        sa, pa = status(), page()
        print(f"a drag from beside the body (pressed {30} px left of its outline, the ray "
              f"{'hit' if pa['lastPress']['hit'] else 'missed'} it): {pa['lastDragTetsCut']} tets cut, cut triangles "
              f"{sb['cut_triangles']} -> {sa['cut_triangles']}", flush=True)
        if pa["lastPress"]["hit"] or pa["lastPress"]["nearest"] is None or pa["lastDragTetsCut"] <= 0 or \
                sa["cut_triangles"] <= sb["cut_triangles"] or pa["noCut"] != pb["noCut"]:
            fail(f"a drag from beside the body: press {pa['lastPress']}, {pa['lastDragTetsCut']} tets cut, cut "
                 f"triangles {sb['cut_triangles']} -> {sa['cut_triangles']}, no-cut flashes {pa['noCut']}")
        driver.save_screenshot(os.path.join(out_dir, "view_beside_cut.png"))

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
