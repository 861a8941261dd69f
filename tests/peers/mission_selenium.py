#!/usr/bin/env python3
"""Plans and flies a mission from the dashboard's Mission tab in real headless Chromium
(a 1366x768 viewport) against `skein up --sim 3` whose geofence the test made a polygon
reaching --fence-north metres north (vehicles landed at home):

1. New plan: takeoff (--altitude), survey, land, abort by landing; the survey's polygon
   drawn by clicks on the plan (closed by a click on its first point), one corner past
   the fence, and its lanes spaced 2 m, under the separation;
2. Store: refused at steps[1].polygon[3] (outside the geofence): the survey's card
   highlighted with the reason, its points marked, the corner ringed on the plan; the
   corner dragged inside, Store: refused at steps[1].lane_spacing_m, that input marked;
   the spacing set to --spacing, Store: the mission is listed, ready, and the lanes the
   plan draws are as many as the coordinator's;
3. Rehearse: the rehearsal runs (mission seconds flown shown), then done: its figures
   (every step done, the closest two vehicles came, the survey's coverage) and its
   picture (an SVG image that loads), no vehicle moved;
4. Start: takeoff, then the survey's lanes flown (the progress row counts them, the plan
   draws the survey with its lanes); Pause: the mission paused and every vehicle
   Hovering; Resume; done, every vehicle Landed;
5. Start again, Skip the survey: the landing begins, done, every vehicle Landed;
6. Start again, Abort mid-survey: the dialog's Cancel leaves it flying, its confirmation
   aborts it (the plan's abort: land): aborted, every vehicle Landed;
7. no severe error in the browser console (but the two refusals' 400s); screenshots
   with --plan-screenshot PATH (the first refusal shown) and --screenshot PATH (paused
   mid-survey).

Every wait polls with a deadline. Prints one JSON summary line; exits 0 only on success.

    python3 tests/peers/mission_selenium.py --url http://127.0.0.1:PORT/ [--screenshot out.png]
        [--plan-screenshot plan.png] [--fence-north 22]
"""

import argparse
import math
import sys
import time

from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

from dashboard_selenium import Dashboard, Failure, add_browser_args, drive

# The plan's view (canvas centre in the swarm frame, px per m, canvas size) and the two
# mission layers' hooks (plan-mission.js).
VIEW_JS = """
const d = document.querySelector('[data-testid="plan-markers"]').dataset;
const c = document.querySelector('[data-testid="plan"]');
const j = (s) => (s ? JSON.parse(s) : null);
return {cn: +d.cn, ce: +d.ce, s: +d.scale, w: c.clientWidth, h: c.clientHeight, moving: d.moving,
        draft: {step: d.draftStep, kind: d.draftKind, points: j(d.draftPoints) || [],
                drawing: d.draftDrawing, error: j(d.draftErrorPoint), lanes: +d.draftLanes},
        flight: {step: d.flightStep, kind: d.flightKind, points: j(d.flightPoints) || [],
                 lanes: +d.flightLanes}};
"""

STATUS_JS = """
const s = document.querySelector('[data-testid="mission-status"]');
const rows = [...document.querySelectorAll('[data-testid="mission-progress"] li[data-step]')];
return {id: s.dataset.missionId || null, state: s.dataset.state || null, step: +s.dataset.step,
        hidden: s.hidden, error: s.querySelector('[data-field="error"]').textContent,
        steps: rows.map(li => ({state: li.dataset.state, lanes_done: li.dataset.lanesDone,
                                lanes_total: li.dataset.lanesTotal,
                                detail: li.querySelector('[data-field="detail"]').textContent}))};
"""

REHEARSAL_JS = """
const b = document.querySelector('[data-testid="mission-rehearsal"]');
const img = b.querySelector('img[data-field="picture"]');
return {hidden: b.hidden, mission: b.dataset.missionId || null, state: b.dataset.state || null,
        outcome: b.dataset.outcome, duration_s: b.dataset.durationS, coverage: b.dataset.coverage,
        min_separation_m: b.dataset.minSeparationM,
        progress: b.querySelector('[data-field="progress"]').textContent,
        figures: b.querySelector('[data-field="figures"]').textContent,
        picture: img.hidden ? 0 : img.naturalWidth, complete: img.complete};
"""

CARD_JS = """
const li = document.querySelector(`[data-testid="mission-step"][data-step="${arguments[0]}"]`);
if (!li) return null;
return {error: li.dataset.error || '', has_error: li.classList.contains('has-error'),
        selected: li.classList.contains('selected'),
        text: li.querySelector('p.m-error').hidden ? '' : li.querySelector('p.m-error').textContent,
        invalid: [...li.querySelectorAll('[aria-invalid="true"]')].map(e => e.dataset.field)};
"""


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", required=True, help="dashboard URL, e.g. http://127.0.0.1:8080/")
    p.add_argument("--screenshot", help="save a PNG of the Mission tab mid-survey here")
    p.add_argument("--plan-screenshot", help="save a PNG of the editor showing the first refusal here")
    p.add_argument("--vehicles", type=int, default=3)
    p.add_argument("--altitude", type=float, default=4.0, help="takeoff altitude, m")
    p.add_argument("--survey-altitude", type=float, default=5.0, help="survey altitude, m")
    p.add_argument("--spacing", type=float, default=4.0, help="the survey's lane spacing once fixed, m")
    p.add_argument("--fence-north", type=float, default=22.0, help="the fence's north edge, m")
    p.add_argument("--timeout", type=float, default=60.0, help="deadline of each step, s")
    add_browser_args(p)
    return p.parse_args()


class MissionTab(Dashboard):
    """The dashboard with the Mission tab's and the plan's hooks."""

    def css(self, sel):
        return self.d.find_element(By.CSS_SELECTOR, sel)

    def press(self, sel):
        """Clicks sel; views re-render from polls: a click that lost its element is retried."""
        def attempt(d):
            try:
                self.css(sel).click()
                return True
            except StaleElementReferenceException:
                return False
        self.wait(f"a click on {sel}", attempt, timeout=5)

    def view(self):
        self.last = self.d.execute_script(VIEW_JS)
        return self.last

    def status(self):
        self.last = self.d.execute_script(STATUS_JS)
        return self.last

    def card(self, i):
        self.last = self.d.execute_script(CARD_JS, i)
        return self.last

    def settled(self):
        """The plan's view once it says it settled (it eases towards its fit) and two polls
        0.2 s apart agree."""
        prev = {}

        def same(d):
            b = self.view()
            ok = bool(prev) and b["moving"] == "false" and abs(prev["s"] - b["s"]) < 0.002 * b["s"] and \
                math.hypot(prev["cn"] - b["cn"], prev["ce"] - b["ce"]) * b["s"] < 0.5
            prev.clear()
            prev.update(b)
            return b if ok else None
        return self.wait("the plan's view to settle", same)

    def at(self, north, east):
        """An action chain at swarm-frame (north, east) on the plan, once the view settled."""
        v = self.settled()
        x = v["w"] / 2 + (east - v["ce"]) * v["s"]
        y = v["h"] / 2 - (north - v["cn"]) * v["s"]
        if not (8 <= x <= v["w"] - 8 and 8 <= y <= v["h"] - 8):
            raise Failure(f"({north}, {east}) is off the plan at ({x:.0f}, {y:.0f}) px: {v}")
        canvas = self.css('[data-testid="plan"]')
        return ActionChains(self.d).move_to_element_with_offset(
            canvas, int(round(x - v["w"] / 2)), int(round(y - v["h"] / 2)))

    def set_field(self, step, field, value):
        el = self.css(f'[data-testid="mission-step"][data-step="{step}"] [data-field="{field}"]')
        el.clear()
        el.send_keys(str(value))

    def store_refused(self, field):
        """Store, and wait for the refusal naming `field`; returns the error shown."""
        self.press('[data-testid="mission-store"]')

        def shown(d):
            box = self.css('[data-testid="mission-plan-error"]')
            self.last = {"field": box.get_attribute("data-field"), "text": box.text}
            return self.last if box.is_displayed() and self.last["field"] == field else None
        return self.wait(f"the refusal naming {field}", shown)


def plan_with_mistakes(ui, args, summary):
    """Step 1: the plan drawn with a corner past the fence and lanes too close."""
    ui.press('[data-testid="tab-mission"]')
    ui.press('[data-testid="mission-new"]')
    ui.wait("the plan editor", lambda d: ui.css('[data-testid="mission-editor"]').is_displayed())
    name = ui.css('[data-testid="mission-name"]')
    name.clear()
    name.send_keys("north field sweep")
    Select(ui.css('[data-testid="mission-editor"] [data-pfield="abort"]')).select_by_value("land")
    for kind in ("takeoff", "survey", "land"):
        ui.press(f'[data-testid="mission-add-{kind}"]')
    ui.wait("three step cards", lambda d: len(d.find_elements(By.CSS_SELECTOR, '[data-testid="mission-step"]')) == 3)
    ui.set_field(0, "altitude_m", f"{args.altitude:g}")
    ui.set_field(1, "altitude_m", f"{args.survey_altitude:g}")
    ui.set_field(1, "lane_spacing_m", "2")
    # Zoomed out a notch: the fence's north edge and beyond are on the plan.
    ui.d.execute_script("arguments[0].dispatchEvent(new WheelEvent('wheel', "
                        "{deltaY: 500, bubbles: true, cancelable: true}))", ui.css('[data-testid="plan"]'))
    ui.press('[data-testid="mission-step"][data-step="1"] [data-act="draw"]')
    ui.wait("the survey drawing", lambda d: ui.view()["draft"]["drawing"] == "polygon")
    top = args.fence_north + 6  # past the fence (and its 2 m margin)
    corners = [(2.0, -4.0), (2.0, 20.0), (17.0, 20.0), (top, -4.0)]
    for i, (north, east) in enumerate(corners):
        ui.at(north, east).click().perform()
        ui.wait(f"corner {i + 1} drawn", lambda d, i=i: len(ui.view()["draft"]["points"]) == i + 1)
    ui.at(*ui.view()["draft"]["points"][0]).click().perform()
    v = ui.wait("the polygon closed on its first corner", lambda d: (lambda v: v if v["draft"]["drawing"] == "" else None)(ui.view()))
    drawn = v["draft"]["points"]
    for (n, e), (gn, ge) in zip(corners, drawn):
        if math.hypot(gn - n, ge - e) > 1.0:
            raise Failure(f"corner drawn at ({gn}, {ge}), meant ({n}, {e})")
    if len(drawn) != 4:
        raise Failure(f"the closing click added a point: {drawn}")
    summary["drawn_corners"] = drawn
    count = ui.css('[data-testid="mission-step"][data-step="1"] [data-field="count"]').text
    if count != "4 points":
        raise Failure(f"the survey card says `{count}`")
    return corners


def fix_and_store(ui, args, summary, corners):
    """Step 2: each refusal shown where it names; fixed; stored."""
    shown = ui.store_refused("steps[1].polygon[3]")
    card = ui.wait("the survey's card highlighted", lambda d: (lambda c: c if c and c["has_error"] else None)(ui.card(1)))
    if card["error"] != "polygon[3]" or "geofence" not in card["text"] or "polygon" not in card["invalid"]:
        raise Failure(f"the survey's card shows {card}")
    ring = ui.wait("the corner ringed on the plan", lambda d: ui.view()["draft"]["error"])
    if math.hypot(ring[0] - corners[3][0], ring[1] - corners[3][1]) > 1.0:
        raise Failure(f"ringed {ring}, the corner past the fence is {corners[3]}")
    if args.plan_screenshot:
        ui.d.save_screenshot(args.plan_screenshot)
        summary["plan_screenshot"] = args.plan_screenshot
    summary["refusals"] = [shown]
    # The corner dragged inside the fence.
    n, e = ui.view()["draft"]["points"][3]
    ui.at(n, e).click_and_hold().perform()
    south_m = n - 17.0
    ActionChains(ui.d).move_by_offset(0, int(round(south_m * ui.view()["s"]))).release().perform()
    moved = ui.wait("the corner dragged to 17 m north", lambda d: (
        lambda p: p if len(p) == 4 and abs(p[3][0] - 17.0) < 1.0 else None)(ui.view()["draft"]["points"]))
    summary["dragged_m"] = round(south_m, 1)
    summary["fixed_corners"] = moved
    ui.wait("the refusal cleared once the corner moved",
            lambda d: ui.view()["draft"]["error"] is None and not ui.card(1)["has_error"], timeout=5)
    shown = ui.store_refused("steps[1].lane_spacing_m")
    card = ui.card(1)
    if card["invalid"] != ["lane_spacing_m"] or "apart" not in card["text"]:
        raise Failure(f"the survey's card shows {card}")
    summary["refusals"].append(shown)
    close_lanes = ui.view()["draft"]["lanes"]
    ui.set_field(1, "lane_spacing_m", f"{args.spacing:g}")
    lanes_drawn = ui.wait(f"the plan to draw the lanes {args.spacing:g} m apart", lambda d: (
        lambda n: n if n not in (0, close_lanes) else None)(ui.view()["draft"]["lanes"]))
    ui.press('[data-testid="mission-store"]')
    st = ui.wait("the stored mission, ready", lambda d: (lambda s: s if not s["hidden"] and s["state"] == "ready" else None)(ui.status()))
    summary["mission"] = st["id"]
    summary["lanes_drawn"] = lanes_drawn
    return st["id"], lanes_drawn


def rehearse(ui, args, summary, mission, lap):
    """Step 3: Rehearse: running, then done with its figures and picture; nothing flew."""
    ui.press('[data-testid="mission-rehearse"]')
    seen = []

    def ended(d):
        r = d.execute_script(REHEARSAL_JS)
        if r["state"] == "running" and r["progress"] not in seen:
            seen.append(r["progress"])
        return r if r["mission"] == mission and r["state"] in ("done", "failed") and r["picture"] else None

    # Virtual time at nice 19 in a debug build beside the swarm: seconds, minutes on a busy CI.
    r = ui.wait("the rehearsal done with its picture", ended, timeout=max(args.timeout, 300))
    summary["rehearsal"] = {k: r[k] for k in ("outcome", "duration_s", "coverage", "min_separation_m", "progress")}
    summary["rehearsal"]["running_seen"] = seen[:3]
    summary["timings_s"]["rehearsed"] = lap()
    if r["state"] != "done" or r["outcome"] != "done":
        raise Failure(f"the rehearsal ended {r}")
    if float(r["coverage"]) <= 0.0 or float(r["min_separation_m"]) <= 0.0:
        raise Failure(f"the rehearsal's figures: {r}")
    for word in ("closest", "coverage", "energy left", "steps done"):
        if word not in r["figures"]:
            raise Failure(f"the figures lack {word!r}: {r['figures']}")
    if not ui.all_rows(args.vehicles, lambda row: row.get("state") == "Landed"):
        raise Failure("a vehicle moved during the rehearsal")
    st = ui.status()
    if st["state"] != "ready":
        raise Failure(f"the mission is {st['state']} after its rehearsal")


def fly(ui, args, summary, lanes_drawn, lap):
    """Step 4: Start, lanes flown, Pause (vehicles hold), Resume, done and landed."""
    n = args.vehicles
    ui.press('[data-testid="mission-start"]')
    ui.wait("the mission running", lambda d: ui.status()["state"] == "running")
    summary["timings_s"]["started"] = lap()
    seen = []

    def lanes_progress(d):
        s = ui.status()
        row = s["steps"][1]
        if row["lanes_total"] and (not seen or seen[-1] != row["lanes_done"]):
            seen.append(row["lanes_done"])
        return row if s["step"] == 1 and row["lanes_done"] and int(row["lanes_done"]) >= 1 else None

    row = ui.wait("the survey's first lane flown", lanes_progress, timeout=max(args.timeout, 90))
    summary["timings_s"]["first_lane"] = lap()
    total = int(row["lanes_total"])
    if total != lanes_drawn:
        raise Failure(f"the coordinator flies {total} lanes, the plan drew {lanes_drawn}")
    flight = ui.wait("the survey and its lanes on the plan",
                     lambda d: (lambda f: f if f["kind"] == "survey" and f["lanes"] == total else None)(ui.view()["flight"]))
    summary["flight_layer"] = {"step": flight["step"], "lanes": flight["lanes"]}
    if ui.d.execute_script("return document.querySelector('[data-testid=\"mission-pause\"]').hidden"):
        raise Failure("no Pause while running")
    ui.press('[data-testid="mission-pause"]')
    ui.wait("the mission paused", lambda d: ui.status()["state"] == "paused")
    ui.wait("every vehicle holding (Hovering)", lambda d: ui.all_rows(n, lambda r: r.get("state") == "Hovering"))
    summary["timings_s"]["paused"] = lap()
    if args.screenshot:
        ui.d.save_screenshot(args.screenshot)
        summary["screenshot"] = args.screenshot
    ui.press('[data-testid="mission-resume"]')
    ui.wait("the mission running again", lambda d: ui.status()["state"] == "running")

    def done(d):
        s = ui.status()
        row = s["steps"][1]
        if row["lanes_done"] and seen[-1] != row["lanes_done"]:
            seen.append(row["lanes_done"])
        return s if s["state"] == "done" else None

    st = ui.wait("the mission done", done, timeout=max(args.timeout, 120))
    summary["lanes_seen"] = seen
    if st["steps"][1]["lanes_done"] != str(total) or any(x["state"] != "done" for x in st["steps"]):
        raise Failure(f"done with {st['steps']}")
    ui.wait("every vehicle Landed", lambda d: ui.all_rows(n, lambda r: r.get("state") == "Landed"), timeout=max(args.timeout, 60))
    summary["timings_s"]["done_landed"] = lap()


def fly_again(ui, args, what):
    """Starts the mission again and waits until its survey flies."""
    ui.press('[data-testid="mission-start"]')
    ui.wait(f"the survey flown again ({what})",
            lambda d: (lambda s: s["state"] == "running" and s["step"] == 1)(ui.status()), timeout=max(args.timeout, 60))


def skip(ui, args, summary, lap):
    """Step 5: flown again, its survey skipped: the landing begins, done, landed."""
    fly_again(ui, args, "to skip it")
    ui.press('[data-testid="mission-skip"]')
    st = ui.wait("the survey skipped, the landing begun", lambda d: (
        lambda s: s if s["step"] == 2 and s["steps"][1]["state"] == "skipped" else None)(ui.status()))
    summary["after_skip"] = [x["state"] for x in st["steps"]]
    ui.wait("the mission done after the skip", lambda d: ui.status()["state"] == "done", timeout=max(args.timeout, 60))
    ui.wait("every vehicle Landed after the skip",
            lambda d: ui.all_rows(args.vehicles, lambda r: r.get("state") == "Landed"), timeout=max(args.timeout, 60))
    summary["timings_s"]["skipped_landed"] = lap()


def abort(ui, args, summary, lap):
    """Step 6: flown again, aborted mid-survey (asked first; Cancel leaves it flying)."""
    fly_again(ui, args, "to abort it")
    ui.press('[data-testid="mission-abort"]')
    ui.wait("the confirmation dialog", lambda d: ui.css('[data-testid="confirm-dialog"]').is_displayed())
    ui.press('[data-testid="confirm-cancel"]')
    ui.wait("the dialog closed", lambda d: not ui.css('[data-testid="confirm-dialog"]').is_displayed())
    if ui.status()["state"] != "running":
        raise Failure(f"the abort was cancelled, yet the mission is {ui.status()['state']}")
    ui.press('[data-testid="mission-abort"]')
    ui.wait("the confirmation dialog again", lambda d: ui.css('[data-testid="confirm-dialog"]').is_displayed())
    ui.press('[data-testid="confirm-ok"]')
    ui.wait("the mission aborted", lambda d: ui.status()["state"] == "aborted", timeout=max(args.timeout, 60))
    summary["after_abort"] = [x["state"] for x in ui.status()["steps"]]
    ui.wait("every vehicle Landed after the abort",
            lambda d: ui.all_rows(args.vehicles, lambda r: r.get("state") == "Landed"), timeout=max(args.timeout, 60))
    summary["timings_s"]["aborted_landed"] = lap()


def console_errors(driver, refusals):
    """Severe console entries but the answers of the refusals the test caused (Chromium
    logs every 4xx as a failed resource load)."""
    severe = [e.get("message", "") for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    refused = [m for m in severe if "/api/v1/missions - Failed to load resource" in m and "status of 400" in m]
    if len(refused) != refusals:
        raise Failure(f"expected {refusals} refusals in the console, saw {refused}")
    return [m for m in severe if m not in refused]


def run(args, driver, summary):
    # The viewport of a 1366x768 laptop (the window's frame would take some of it).
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": 1366, "height": 768, "deviceScaleFactor": 1, "mobile": False})
    ui = MissionTab(driver, args.timeout)
    t0 = time.monotonic()
    lap = lambda: round(time.monotonic() - t0, 1)  # noqa: E731
    summary["timings_s"] = {}
    ui.open(args.url)
    ui.wait(f"{args.vehicles} vehicles Landed", lambda d: ui.all_rows(args.vehicles, lambda r: r.get("state") == "Landed"))
    ui.wait("the plan's markers", lambda d: len(ui.markers()) == args.vehicles)
    corners = plan_with_mistakes(ui, args, summary)
    fix_and_store(ui, args, summary, corners)
    summary["timings_s"]["stored"] = lap()
    rehearse(ui, args, summary, summary["mission"], lap)
    fly(ui, args, summary, summary["lanes_drawn"], lap)
    skip(ui, args, summary, lap)
    abort(ui, args, summary, lap)
    errors = console_errors(driver, len(summary["refusals"]))
    summary["console_errors"] = errors
    if errors:
        raise Failure(f"browser console errors: {errors}")


def on_failure(driver, summary):
    summary["status"] = driver.execute_script(STATUS_JS)
    summary["view"] = driver.execute_script(VIEW_JS)
    summary["toasts"] = driver.execute_script(
        "return [...document.querySelectorAll('#toasts .toast')].map(t => t.textContent)")
    # Each vehicle as the API has it (its fence state and breach among them): a vehicle
    # that ended in a failsafe says why (once, in CI, one ended in HOLD while landing).
    summary["vehicles_api"] = driver.execute_script(
        "return fetch('/api/v1/vehicles').then(r => r.text())")


if __name__ == "__main__":
    sys.exit(drive(parse_args(), run, on_failure))
