#!/usr/bin/python3
"""The README's first-scene picture: `incise view RUN` in headless Chromium, the last frame
coloured by von Mises stress, saved as a PNG (scripts/first-scene.sh).

usage: first_scene_picture.py INCISE RUN_DIR OUT.png
"""
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "view"))
from browser_look_test import Viewer  # noqa: E402
from browser_util import start_chromium, wait_for  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.support.ui import Select  # noqa: E402


def main():
    incise, run, png = sys.argv[1:4]
    viewer = Viewer(incise, run)
    driver = start_chromium()
    page = lambda: driver.execute_script("return window.inciseView || null")
    try:
        driver.get(viewer.url)
        wait_for("the page to draw", lambda: (page() or {}).get("triangles", 0) > 0)
        last = viewer.status()["frames"] - 1
        driver.execute_script(f"const e = document.getElementById('frame'); e.value = '{last}'; "
                              "e.dispatchEvent(new Event('input'));")
        wait_for("the last frame", lambda: viewer.status()["frame"] == last and page()["frame"] == last)
        Select(driver.find_element(By.ID, "colour")).select_by_value("1")
        wait_for("stress colours", lambda: viewer.status()["colour"] == 1 and
                 (page()["legend"] or {}).get("kind") == "scale")
        time.sleep(1.0)  # a rendered frame
        driver.save_screenshot(png)
        print("wrote", png)
    finally:
        driver.quit()
        viewer.stop()


if __name__ == "__main__":
    main()
