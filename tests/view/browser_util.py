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
