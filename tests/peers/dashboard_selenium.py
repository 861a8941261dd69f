#!/usr/bin/env python3
"""Drives the skein dashboard in real headless Chromium (Selenium 4, Debian's chromium and
chromedriver) against a fresh `skein up --sim 3`:

1. load the page, wait for the connection indicator `connected`, the load indicator and 3
   vehicle rows; the Pre-flight tab shows every vehicle ready, and its RTK form takes a UDP
   corrections source (this script sends pyrtcm's RTCM3 base station frames to it): the
   source streams, the base station and every vehicle's corrections show, Stop idles it;
2. Take off (10 m): all rows `Hovering` at 10 +- 1 m;
3. Line (7 m): all rows `InFormation`; the plan view's markers are distinct and on a line
   along east (equal north / equal pixel y within tolerance);
4. every shape is offered; Wedge behind the `virtual` leader, then the leader's Go to 15 m
   north: the formation status names both, and the markers follow the leader;
   with --sim-stats, uav-3's simulated link is cut: the header's rms error says it is
   absent (`1 absent`, `data-absent="uav-3"`) until the link is back;
5. Land (confirmed in the dialog): all rows `Landed`;
6. no errors in the browser console, and the event log has a `state_changed` entry;
7. optional screenshot (taken in formation) with --screenshot PATH.

Every wait polls with a deadline (WebDriverWait). Prints one JSON summary line; exits 0
only on success.

    python3 tests/peers/dashboard_selenium.py --url http://127.0.0.1:PORT/ [--screenshot out.png]
"""

import argparse
import json
import math
import sys
import time

from selenium import webdriver
from selenium.common.exceptions import TimeoutException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select, WebDriverWait

# Reads the whole table in one round trip: {id: {field: text}}.
ROWS_JS = """
const out = {};
for (const tr of document.querySelectorAll('tr[data-vehicle-id]')) {
  const row = {};
  for (const c of tr.querySelectorAll('[data-field]')) row[c.dataset.field] = c.textContent.trim();
  out[tr.dataset.vehicleId] = row;
}
return out;
"""

# The plan view's mirror of its drawn markers.
MARKERS_JS = """
return [...document.querySelectorAll('[data-testid="plan-markers"] [data-vehicle-id]')].map(li => ({
  id: li.dataset.vehicleId, x: +li.dataset.x, y: +li.dataset.y,
  north: +li.dataset.north, east: +li.dataset.east, state: li.dataset.state,
}));
"""


class Failure(Exception):
    pass


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", required=True, help="dashboard URL, e.g. http://127.0.0.1:8080/")
    p.add_argument("--screenshot", help="save a PNG of the dashboard in formation here")
    p.add_argument("--sim-stats", help="host:port of the simulator's stats socket: cut a link")
    p.add_argument("--vehicles", type=int, default=3, help="expected number of vehicles")
    p.add_argument("--altitude", type=float, default=10.0, help="takeoff altitude, m")
    p.add_argument("--spacing", type=float, default=7.0, help="line spacing, m")
    p.add_argument("--timeout", type=float, default=45.0, help="deadline of each step, s")
    add_browser_args(p)
    return p.parse_args()


def no_console_errors(driver):
    """Raises Failure when the browser console holds a severe error."""
    severe = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    if severe:
        raise Failure(f"browser console errors: {severe}")


def add_browser_args(p):
    """The browser options of every dashboard script: --chromium, --chromedriver, --headed."""
    p.add_argument("--chromium", default="/usr/bin/chromium")
    p.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    p.add_argument("--headed", action="store_true", help="show the browser window")


def drive(args, run, on_failure=None):
    """Runs run(args, driver, summary) in a fresh browser, prints the summary as one JSON
    line and returns the exit code (0 only on success). On a failure, on_failure(driver,
    summary) may add what the browser shows before it closes."""
    summary = {"ok": False}
    driver = make_driver(args)
    try:
        run(args, driver, summary)
        summary["ok"] = True
    except Exception as e:  # noqa: BLE001 - reported in the summary
        summary["error"] = str(e)
        if on_failure is not None:
            try:
                on_failure(driver, summary)
            except Exception:  # noqa: BLE001 - diagnostics only
                pass
    finally:
        driver.quit()
    print(json.dumps(summary))
    return 0 if summary["ok"] else 1


def make_driver(args):
    opts = webdriver.ChromeOptions()
    opts.binary_location = args.chromium
    if not args.headed:
        opts.add_argument("--headless=new")
    for a in ("--no-sandbox", "--disable-dev-shm-usage", "--window-size=1440,900",
              "--disable-gpu", "--no-first-run", "--disable-extensions"):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    # An explicit driver path: Selenium Manager is not asked to download anything.
    return webdriver.Chrome(service=Service(executable_path=args.chromedriver), options=opts)


class Dashboard:
    def __init__(self, driver, timeout):
        self.d = driver
        self.timeout = timeout
        self.last = None  # last observed value, for failure messages

    def wait(self, what, cond, timeout=None):
        """Polls cond(driver) until it returns a truthy value; Failure on the deadline."""
        def probe(d):
            v = cond(d)
            return v
        try:
            return WebDriverWait(self.d, timeout or self.timeout, poll_frequency=0.2).until(probe)
        except TimeoutException:
            raise Failure(f"timed out after {timeout or self.timeout:.0f} s waiting for {what}; "
                          f"last seen: {json.dumps(self.last)}") from None

    def open(self, url, what="the connection indicator to read `connected`"):
        """Loads the dashboard at url and waits until its stream is connected."""
        self.d.get(url)
        self.wait(what, lambda d: d.find_element(
            By.CSS_SELECTOR, '[data-testid="connection"]').text.strip() == "connected")

    def rows(self):
        self.last = self.d.execute_script(ROWS_JS)
        return self.last

    def markers(self):
        self.last = self.d.execute_script(MARKERS_JS)
        return self.last

    def click(self, testid):
        self.d.find_element(By.CSS_SELECTOR, f'[data-testid="{testid}"]').click()

    def set_input(self, testid, value):
        el = self.d.find_element(By.CSS_SELECTOR, f'[data-testid="{testid}"]')
        el.clear()
        el.send_keys(str(value))

    def all_rows(self, n, pred):
        rows = self.rows()
        return rows if len(rows) == n and all(pred(r) for r in rows.values()) else None


def altitude(row):
    try:
        return float(row.get("altitude", ""))
    except ValueError:
        return math.nan


def collinear_line(markers, n, spacing):
    """The markers if n distinct ones lie on a line along east (heading 0), else None."""
    if len(markers) != n:
        return None
    for i, a in enumerate(markers):
        for b in markers[i + 1:]:
            if math.hypot(a["x"] - b["x"], a["y"] - b["y"]) < 10:
                return None  # not distinct on screen
    xs = [m["x"] for m in markers]
    ys = [m["y"] for m in markers]
    norths = [m["north"] for m in markers]
    easts = sorted(m["east"] for m in markers)
    x_span, y_span = max(xs) - min(xs), max(ys) - min(ys)
    if y_span > max(3.0, 0.03 * x_span):
        return None  # pixel rows differ: not a line along east
    if max(norths) - min(norths) > 0.3:
        return None
    gaps = [b - a for a, b in zip(easts, easts[1:])]
    if any(abs(g - spacing) > 0.5 for g in gaps):
        return None
    return {"x_span_px": round(x_span, 1), "y_span_px": round(y_span, 1),
            "north_span_m": round(max(norths) - min(norths), 2),
            "east_gaps_m": [round(g, 2) for g in gaps]}


def wedge_norths(markers, n, spacing):
    """Each marker's north (m, by vehicle id) if n markers stand in a wedge of this spacing
    (m): one ahead of all others by at least 0.55 spacing (a wedge's rank is spacing x
    cos 45 deg = 0.71 spacing behind), the rest in pairs level within 0.5 m; else None."""
    if len(markers) != n or n < 3:
        return None
    ms = sorted(markers, key=lambda m: -m["north"])
    if ms[0]["north"] - ms[1]["north"] < 0.55 * spacing:
        return None
    rest = ms[1:]
    if any(abs(a["north"] - b["north"]) > 0.5 for a, b in zip(rest[0::2], rest[1::2])):
        return None
    return {m["id"]: m["north"] for m in markers}


def run(args, driver, summary):
    ui = Dashboard(driver, args.timeout)
    n = args.vehicles
    t0 = time.monotonic()
    lap = lambda: round(time.monotonic() - t0, 1)  # noqa: E731

    # 1. Page, stream, rows.
    ui.open(args.url)
    # The load indicator (every `vehicles` frame carries the process's load).
    ui.wait("the load indicator to show the process's load",
            lambda d: d.find_element(By.CSS_SELECTOR, '[data-testid="load"]').get_attribute("data-level")
            in ("normal", "shedding"))
    summary["load"] = driver.find_element(By.CSS_SELECTOR, '[data-testid="load"]').text.strip()
    ui.wait(f"{n} vehicle rows", lambda d: len(ui.rows()) == n)
    summary["vehicles"] = sorted(ui.rows())
    summary["timings_s"]["connected"] = lap()
    ui.wait("all vehicles Landed before takeoff", lambda d: ui.all_rows(n, lambda r: r.get("state") == "Landed"))

    # 1b. The fleet's pre-flight checks: every vehicle ready, PX4's own checks passing.
    ui.click("tab-preflight")

    def preflight(d):
        rows = d.execute_script(
            "return [...document.querySelectorAll('[data-testid=\"preflight\"] tbody tr')].map(tr => ({"
            "id: tr.dataset.vehicle, ready: tr.dataset.ready, checks: Object.fromEntries("
            "[...tr.querySelectorAll('td[data-check]')].map(td => [td.dataset.check, td.dataset.state || null]))}))")
        ready = len(rows) == n and all(
            r["ready"] == "true" and r["checks"].get("px4_arming_checks") == "ok"
            and r["checks"].get("gnss") == "ok" and r["checks"].get("link") == "ok" for r in rows)
        return rows if ready else None

    summary["preflight"] = ui.wait("the pre-flight tab to show every vehicle ready", preflight)
    summary["rtk"] = rtk_from_the_form(ui, n)
    ui.click("tab-swarm")

    # 2. Take off.
    ui.set_input("takeoff-altitude", f"{args.altitude:g}")
    ui.click("takeoff")
    rows = ui.wait(f"all rows Hovering at {args.altitude:g} +- 1 m", lambda d: ui.all_rows(
        n, lambda r: r.get("state") == "Hovering" and abs(altitude(r) - args.altitude) <= 1.0))
    summary["timings_s"]["hovering"] = lap()
    summary["hover_altitudes_m"] = {k: altitude(v) for k, v in sorted(rows.items())}

    # 3. Line formation.
    ui.set_input("formation-spacing", f"{args.spacing:g}")
    ui.click("line")
    ui.wait("all rows InFormation", lambda d: ui.all_rows(n, lambda r: r.get("state") == "InFormation"))
    summary["timings_s"]["in_formation"] = lap()
    line = ui.wait("the plan markers to form a line along east",
                   lambda d: collinear_line(ui.markers(), n, args.spacing))
    summary["timings_s"]["line_settled"] = lap()
    summary["line"] = line
    summary["markers"] = [{k: m[k] for k in ("id", "x", "y", "north", "east")} for m in ui.markers()]
    if args.screenshot:
        driver.save_screenshot(args.screenshot)
        summary["screenshot"] = args.screenshot

    # 4. Every shape offered; a wedge behind the virtual leader, which the operator drives.
    shapes = driver.execute_script(
        "return [...document.querySelectorAll('#shape-buttons [data-shape]')].map(b => b.dataset.shape)")
    summary["shapes_offered"] = shapes
    expected = {"line", "column", "wedge", "echelon_left", "echelon_right", "diamond", "circle", "grid"}
    if set(shapes) != expected:
        raise Failure(f"shape buttons {shapes}, expected {sorted(expected)}")
    Select(driver.find_element(By.CSS_SELECTOR, '[data-testid="formation-leader"]')).select_by_value("virtual")
    ui.click("wedge")

    def status_text(d):
        return d.find_element(By.CSS_SELECTOR, '[data-testid="formation-status"]').text

    ui.wait("the formation status to read a wedge behind the virtual leader",
            lambda d: "wedge" in status_text(d) and "leader virtual" in status_text(d))
    ui.wait("all rows InFormation in the wedge", lambda d: ui.all_rows(n, lambda r: r.get("state") == "InFormation"))
    # The rows read InFormation from the line until the members leave it: the start is
    # taken once the markers stand in a wedge (each member's own north: the wedge's mean
    # lies behind its leader, by how much depends on when it is read).
    start = ui.wait("the markers to stand in a wedge", lambda d: wedge_norths(ui.markers(), n, args.spacing))
    north0 = max(start.values())
    ui.set_input("leader-north", f"{north0 + 15:.0f}")
    ui.set_input("leader-east", "0")
    ui.set_input("leader-speed", "3")
    ui.click("leader-goto")

    def followed(d):
        ms = ui.markers()
        if len(ms) != n or any(m["id"] not in start or m["north"] < start[m["id"]] + 12 for m in ms):
            return None
        return max(m["north"] for m in ms)

    summary["leader_goto_north_m"] = [round(north0, 1), round(ui.wait("the markers to follow the leader north", followed), 1)]
    summary["timings_s"]["followed_leader"] = lap()

    # 4b. A member out of the formation is not out of its figures: uav-3's link cut, the
    # header's rms error says one member is absent, and which.
    if args.sim_stats:
        sim_link(args.sim_stats, 3, 1.0)

        def absent(d):
            el = d.find_element(By.ID, "sum-rms")
            ids = el.get_attribute("data-absent") or ""
            return {"text": el.text, "ids": ids} if ids == "uav-3" and "1 absent" in el.text else None

        summary["absent_shown"] = ui.wait("the header to show uav-3 absent", absent, timeout=max(args.timeout, 30))
        summary["timings_s"]["absent_shown"] = lap()
        sim_link(args.sim_stats, 3, 0.0)

    # 5. Land (every vehicle: the dashboard asks for confirmation first).
    ui.click("land")
    ui.wait("the confirmation dialog", lambda d: d.find_element(By.CSS_SELECTOR, '[data-testid="confirm-dialog"]').is_displayed())
    ui.click("confirm-ok")
    ui.wait("all rows Landed", lambda d: ui.all_rows(n, lambda r: r.get("state") == "Landed"), timeout=max(args.timeout, 60))
    summary["timings_s"]["landed"] = lap()

    # 5b. Every vehicle's flight log brought home (Pre-flight & logs tab). A vehicle
    # disarms about 2 s after touchdown, when its log ends: ask again until all three are
    # there (a log fetched already is not fetched twice).
    ui.click("tab-preflight")
    asked = [0.0]

    def logs_home(d):
        rows = d.execute_script(
            "return [...document.querySelectorAll('tr[data-log]')].map(tr => ({log: tr.dataset.log, "
            "state: tr.dataset.state, file: !!tr.querySelector('a[data-testid=\"log-file\"]')}))")
        if len(rows) == n and all(r["state"] == "complete" and r["file"] for r in rows):
            return rows
        if time.monotonic() - asked[0] > 5 and not any(r["state"] == "downloading" for r in rows):
            asked[0] = time.monotonic()
            ui.click("fetch-logs")
        return None

    summary["flight_logs"] = ui.wait("every vehicle's flight log downloaded", logs_home, timeout=max(args.timeout, 90))
    summary["timings_s"]["logs_home"] = lap()
    ui.click("tab-swarm")

    # 6. Event log and console.
    kinds = driver.execute_script(
        "return [...document.querySelectorAll('[data-testid=\"event-log\"] li')].map(li => li.dataset.type)")
    summary["event_log_entries"] = len(kinds)
    summary["state_changed_entries"] = kinds.count("state_changed")
    if not kinds.count("state_changed"):
        raise Failure("the event log shows no state_changed entry")
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    summary["console_errors"] = [e.get("message") for e in errors]
    if errors:
        raise Failure(f"{len(errors)} console error(s): {summary['console_errors']}")


def rtk_from_the_form(ui, n):
    """Sets a UDP corrections source in the Pre-flight tab's RTK form, sends RTCM3 base
    station frames (1005, made with pyrtcm by rtcm_base.py) to it until the page shows the
    source streaming with the base station and corrections sent to all n vehicles; then
    Stop: idle again. Returns what the page showed."""
    import socket
    from rtcm_base import ecef, frame, msg_1005
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    base = frame(msg_1005(7, ecef(47.3980, 8.5460, 520.0)), 1005)
    ui.set_input("rtk-source", f"udp://127.0.0.1:{port}")
    ui.d.find_element(By.CSS_SELECTOR, '[data-testid="rtk-form"] button[type="submit"]').click()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def streaming(d):
        tx.sendto(base, ("127.0.0.1", port))
        shown = d.execute_script(
            "return {state: document.querySelector('[data-testid=\"rtk-state\"]').dataset.state,"
            " base: document.querySelector('[data-field=\"rtk-base\"]').textContent,"
            " rows: [...document.querySelectorAll('tr[data-rtk-vehicle]')].map(tr => tr.cells[2].textContent)}")
        ui.last = shown
        fresh = len(shown["rows"]) == n and all(r.endswith("s old") for r in shown["rows"])
        return shown if shown["state"] == "streaming" and "base station 7" in shown["base"] and fresh else None

    shown = ui.wait("the RTK source streaming to every vehicle", streaming)
    ui.click("rtk-stop")
    ui.wait("the RTK source idle after Stop", lambda d: d.find_element(
        By.CSS_SELECTOR, '[data-testid="rtk-state"]').get_attribute("data-state") == "idle")
    return shown


def sim_link(addr, sysid, loss):
    """Sets the simulated link quality of vehicle `sysid` through the simulator's stats
    socket (`link <sysid> <loss 0..1> <latency_ms>`)."""
    import socket
    host, port = addr.rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(f"link {sysid} {loss:g} 0\n".encode())
        answer = s.makefile().readline()
    if '"ok":true' not in answer.replace(" ", ""):
        raise Failure(f"link {sysid} {loss}: {answer!r}")


def main():
    args = parse_args()
    summary = {"ok": False, "url": args.url, "timings_s": {}}
    started = time.monotonic()
    driver = None
    code = 1
    try:
        driver = make_driver(args)
        run(args, driver, summary)
        summary["ok"] = True
        code = 0
    except Failure as e:
        summary["error"] = str(e)
    except WebDriverException as e:
        summary["error"] = f"webdriver: {e.msg or e}"
    except Exception as e:  # noqa: BLE001 - report anything as a failed run
        summary["error"] = f"{type(e).__name__}: {e}"
    finally:
        if driver is not None:
            if code != 0 and "console_errors" not in summary:
                try:
                    summary["console_errors"] = [e.get("message") for e in driver.get_log("browser")
                                                 if e.get("level") == "SEVERE"]
                except WebDriverException:
                    pass
            if code != 0 and args.screenshot:
                try:
                    driver.save_screenshot(args.screenshot)
                    summary["screenshot"] = args.screenshot
                except WebDriverException:
                    pass
            try:
                driver.quit()
            except WebDriverException:
                pass
    summary["elapsed_s"] = round(time.monotonic() - started, 1)
    print(json.dumps(summary))
    return code


if __name__ == "__main__":
    sys.exit(main())
