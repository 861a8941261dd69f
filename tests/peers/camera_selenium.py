#!/usr/bin/env python3
"""Drives the dashboard's camera card in real headless Chromium against a running `skein
up` whose vehicle carries a real (RTSP) camera: opens the Payloads tab of `--vehicle`,
finds the card of `--slot` and waits until it shows the source in `--expect`:

- `streaming`: the widget's data-source-state is `streaming`, the video shows a picture
  (naturalWidth > 0) at full opacity, and no "camera …" warning is shown;
- `stalled` (or `connecting`, `failed`): data-source-state says so, the video is dimmed
  (computed opacity below 1) and the status line reads "camera STALLED: <reason>";

and no severe error in the browser console. Prints one JSON summary line; exits 0 only on
success.

    python3 tests/peers/camera_selenium.py --url http://127.0.0.1:PORT/ --vehicle uav-1 \\
        --slot camera --expect stalled [--screenshot out.png]
"""

import argparse
import sys

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

from dashboard_selenium import Dashboard, add_browser_args, drive, no_console_errors

CARD_JS = """
const card = document.querySelector(`[data-testid="payload-card"][data-slot="${arguments[0]}"]`);
const w = card && card.querySelector('.widget');
if (!w) return null;
const img = w.querySelector('img[data-testid="camera-video"]');
return {state: w.dataset.sourceState || null, status: w.querySelector('.video-status').textContent,
        opacity: +getComputedStyle(img).opacity, natural_width: img.naturalWidth};
"""


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", required=True)
    p.add_argument("--vehicle", required=True)
    p.add_argument("--slot", default="camera")
    p.add_argument("--expect", required=True, choices=["streaming", "stalled", "connecting", "failed"])
    p.add_argument("--screenshot")
    p.add_argument("--timeout", type=float, default=60.0)
    add_browser_args(p)
    return p.parse_args()


def run(args, driver, summary):
    ui = Dashboard(driver, args.timeout)
    ui.open(args.url)
    ui.click("tab-payloads")
    Select(driver.find_element(By.CSS_SELECTOR, '[data-testid="payload-vehicle"]')).select_by_value(args.vehicle)

    def shown(_):
        ui.last = driver.execute_script(CARD_JS, args.slot)
        c = ui.last
        if not c or c["state"] != args.expect:
            return False
        if args.expect == "streaming":
            return c["natural_width"] > 0 and c["opacity"] == 1 and not c["status"].startswith("camera")
        return c["opacity"] < 1 and c["status"].startswith(f"camera {args.expect.upper()}:")
    ui.wait(f"{args.vehicle}/{args.slot} shown {args.expect}", shown)
    summary["card"] = ui.last
    if args.screenshot:
        driver.save_screenshot(args.screenshot)
    no_console_errors(driver)


def main():
    args = parse_args()

    def on_failure(driver, summary):
        summary["card"] = driver.execute_script(CARD_JS, args.slot)
        if args.screenshot:
            driver.save_screenshot(args.screenshot)

    return drive(args, run, on_failure)


if __name__ == "__main__":
    sys.exit(main())
