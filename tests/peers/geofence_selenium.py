#!/usr/bin/env python3
"""The map and the geofence in real headless Chromium against `skein up --sim 3
--map-tiles field.mbtiles` whose vehicles hover, the tiles written by the test so that a
tile's colour says which tile it is (red 24 + 8 (x mod 16), green 24 + 8 (y mod 16), blue
24 + 8 (z mod 16), XYZ numbering):

1. the map is drawn (source mbtiles, overzoomed past its deepest level 18) and, under
   each vehicle's marker, the map's pixel is the colour of the tile that holds the
   vehicle's latitude / longitude (the server turned the file's TMS rows right);
2. the cursor's latitude / longitude over a marker is the vehicle's; the attribution is
   shown;
3. zoomed out, the hole in the set (--hole-north metres north of the origin) is no tile:
   the map canvas is empty there, so the plan's grid shows;
4. the operator edits the fence: draws a polygon around the swarm on the plan, applies
   it, and every row shows the autopilot holding the next version;
5. waits for the test to fly --breach across the fence: its row reads BREACH, the event
   log has the geofence_breach, and the plan rings it; screenshot.

Prints one JSON summary line; exits 0 only on success.

    python3 tests/peers/geofence_selenium.py --url http://127.0.0.1:PORT/ --api http://127.0.0.1:PORT
"""

import argparse
import json
import math
import sys
import time
import urllib.request

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By

from dashboard_selenium import Dashboard, Failure, add_browser_args, drive

VIEW_JS = """
const d = document.querySelector('[data-testid="plan-markers"]').dataset;
const c = document.querySelector('[data-testid="plan"]');
return {cn: +d.cn, ce: +d.ce, s: +d.scale, w: c.clientWidth, h: c.clientHeight,
        source: d.mapSource, zoom: d.mapZoom === '' ? null : +d.mapZoom, tiles: +d.mapTiles,
        missing: +d.mapMissing, lat0: d.originLat === '' ? null : +d.originLat,
        lon0: d.originLon === '' ? null : +d.originLon, cursor: d.cursorGeo || '',
        editing: d.fenceEditing, vertices: JSON.parse(d.fenceVertices || '[]')};
"""

# The map canvas's RGBA at CSS pixel (x, y).
PIXEL_JS = """
const c = document.querySelector('[data-testid="plan-map"]');
const k = c.width / c.clientWidth;
return Array.from(c.getContext('2d').getImageData(Math.round(arguments[0] * k),
                                                   Math.round(arguments[1] * k), 1, 1).data);
"""

MARKERS_JS = """
return [...document.querySelectorAll('[data-testid="plan-markers"] [data-vehicle-id]')].map(li => ({
  id: li.dataset.vehicleId, x: +li.dataset.x, y: +li.dataset.y}));
"""

FENCE_CELLS_JS = """
const out = {};
for (const tr of document.querySelectorAll('tr[data-vehicle-id]')) {
  const td = tr.querySelector('[data-field="fence"]');
  out[tr.dataset.vehicleId] = td ? td.textContent.trim() : '';
}
return out;
"""


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", required=True)
    p.add_argument("--api", required=True, help="skein's base URL (for the vehicles' positions)")
    p.add_argument("--screenshot")
    p.add_argument("--hole-north", type=float, default=300.0)
    p.add_argument("--breach", default="uav-3", help="the vehicle the test flies out")
    p.add_argument("--vehicles", type=int, default=3)
    p.add_argument("--timeout", type=float, default=45.0)
    add_browser_args(p)
    return p.parse_args()


def api(base, path):
    with urllib.request.urlopen(base + path, timeout=10) as r:
        return json.loads(r.read())


def tile_of(lat, lon, z):
    n = 2 ** z
    x = math.floor((lon + 180) / 360 * n)
    r = math.radians(lat)
    y = math.floor((1 - math.log(math.tan(r) + 1 / math.cos(r)) / math.pi) / 2 * n)
    return x, y


def decode(rgba):
    """(x mod 16, y mod 16, z mod 16) of a tile's colour, or None for no tile."""
    if rgba[3] < 250:
        return None
    return tuple(round((c - 24) / 8) % 16 for c in rgba[:3])


def run(args, driver, summary):
    ui = Dashboard(driver, args.timeout)
    n = args.vehicles
    t0 = time.monotonic()
    lap = lambda: round(time.monotonic() - t0, 1)  # noqa: E731
    timings = summary.setdefault("timings_s", {})

    def view():
        ui.last = driver.execute_script(VIEW_JS)
        return ui.last

    def settled():
        """The view once two successive polls (0.2 s apart) agree: the plan eases its view."""
        prev = {}

        def same(d):
            b = view()
            # Still: under a pixel of movement, the same zoom level and tiles.
            ok = (bool(prev) and b["tiles"] > 0 and prev["zoom"] == b["zoom"] and prev["tiles"] == b["tiles"]
                  and abs(prev["s"] - b["s"]) < 0.002 * b["s"]
                  and math.hypot(prev["cn"] - b["cn"], prev["ce"] - b["ce"]) * b["s"] < 1.0)
            prev.clear()
            prev.update(b)
            return b if ok else None
        return ui.wait("the plan's view to settle with its map drawn", same)

    def px(v, north, east):
        return v["w"] / 2 + (east - v["ce"]) * v["s"], v["h"] / 2 - (north - v["cn"]) * v["s"]

    def at(x, y):
        """An action chain moved to CSS pixel (x, y) of the plan's canvas."""
        r = canvas.rect
        return ActionChains(driver).move_to_element_with_offset(
            canvas, int(round(x - r["width"] / 2)), int(round(y - r["height"] / 2)))

    # 1. The page, the vehicles, the map.
    ui.open(args.url)
    canvas = driver.find_element(By.CSS_SELECTOR, '[data-testid="plan"]')
    ui.wait(f"{n} vehicle rows", lambda d: len(ui.rows()) == n)
    ui.wait("the map and the swarm origin", lambda d: view()["source"] == "mbtiles" and view()["lat0"] is not None)
    v = settled()
    summary["map"] = {k: v[k] for k in ("source", "zoom", "tiles", "lat0", "lon0")}
    if v["zoom"] != 18:
        raise Failure(f"expected the set's deepest level 18 (overzoomed), the map draws {v['zoom']}")
    timings["map"] = lap()

    vehicles = {x["id"]: x for x in api(args.api, "/api/v1/vehicles")}
    markers = ui.wait(f"{n} markers", lambda d: (lambda m: m if len(m) == n else None)(driver.execute_script(MARKERS_JS)))
    under = {}
    for m in markers:
        pos = vehicles[m["id"]]["position"]
        tx, ty = tile_of(pos["lat_deg"], pos["lon_deg"], v["zoom"])
        want = (tx % 16, ty % 16, v["zoom"] % 16)
        got = decode(driver.execute_script(PIXEL_JS, m["x"], m["y"]))
        flipped = (tx % 16, (2 ** v["zoom"] - 1 - ty) % 16, v["zoom"] % 16)
        under[m["id"]] = {"tile": [v["zoom"], tx, ty], "seen": got}
        if got != want:
            hint = " (the TMS row, not flipped)" if got == flipped else ""
            raise Failure(f"{m['id']}: under its marker the map shows tile {got}{hint}, expected {want}")
    summary["tiles_under_markers"] = under

    # 2. The cursor's latitude / longitude over uav-1; the attribution.
    m1 = next(m for m in markers if m["id"] == "uav-1")
    at(m1["x"], m1["y"]).perform()
    cursor = ui.wait("the cursor's latitude / longitude", lambda d: view()["cursor"] or None)
    lat, lon = (float(c) for c in cursor.split(","))
    p1 = vehicles["uav-1"]["position"]
    off_m = math.hypot((lat - p1["lat_deg"]) * 111_195, (lon - p1["lon_deg"]) * 111_195 * math.cos(math.radians(lat)))
    summary["cursor"] = {"geo": cursor, "off_uav_1_m": round(off_m, 2)}
    if off_m > 1.0:
        raise Failure(f"the cursor over uav-1 reads {cursor}, {off_m:.1f} m from uav-1")
    credit = driver.find_element(By.CSS_SELECTOR, '[data-testid="map-attribution"]')
    if not credit.is_displayed() or "test tiles" not in credit.text:
        raise Failure(f"attribution `{credit.text}` (displayed: {credit.is_displayed()})")

    # 3. Zoomed out: the hole is no tile, the grid shows there.
    for _ in range(4):
        driver.execute_script(
            "arguments[0].dispatchEvent(new WheelEvent('wheel', {deltaY: 1000, bubbles: true, cancelable: true}))", canvas)
    v = settled()
    hx, hy = px(v, args.hole_north, 0.0)
    if not (0 <= hx < v["w"] and 0 <= hy < v["h"]):
        raise Failure(f"the hole at {args.hole_north} m north is off the plan zoomed out ({hx:.0f}, {hy:.0f})")
    hole = driver.execute_script(PIXEL_JS, hx, hy)
    vx, vy = px(v, 0.0, 0.0)
    home = driver.execute_script(PIXEL_JS, vx, vy)
    summary["zoomed_out"] = {"zoom": v["zoom"], "tiles": v["tiles"], "missing": v["missing"], "hole_rgba": hole, "origin_rgba": home}
    if hole[3] != 0 or v["missing"] < 1:
        raise Failure(f"the hole shows {hole} (missing tiles {v['missing']}), expected no tile")
    if home[3] != 255:
        raise Failure(f"no tile at the origin zoomed out: {home}")
    timings["hole"] = lap()

    # 4. The operator draws the fence around the swarm and applies it.
    ui.click("plan-fit")
    driver.execute_script(
        "arguments[0].dispatchEvent(new WheelEvent('wheel', {deltaY: 1200, bubbles: true, cancelable: true}))", canvas)
    settled()
    ui.click("fence-edit")
    ui.click("fence-draw-polygon")
    drawn = [(-30.0, -30.0), (-30.0, 30.0), (40.0, 30.0), (40.0, -30.0)]
    for i, (north, east) in enumerate(drawn):
        v = settled()
        x, y = px(v, north, east)
        at(x, y).click().perform()
        ui.wait(f"vertex {i}", lambda d, i=i: len(view()["vertices"]) == i + 1)
    ui.click("fence-finish")
    got = view()["vertices"]
    summary["drawn_vertices"] = got
    for (north, east), (gn, ge) in zip(drawn, got):
        if math.hypot(gn - north, ge - east) > 3.0:
            raise Failure(f"vertex drawn at ({gn}, {ge}), meant ({north}, {east})")
    ui.set_input("fence-ceiling", "60")
    versions = [t.rsplit(" v", 1) for t in driver.execute_script(FENCE_CELLS_JS).values()]
    before = max(int(v[1]) for v in versions if len(v) == 2 and v[1].isdigit())
    want = f"synced v{before + 1}"
    ui.click("fence-apply")
    cells = ui.wait(f"every vehicle's autopilot holding fence version {before + 1}", lambda d: (
        lambda c: c if len(c) == n and all(t == want for t in c.values()) else None)(
            driver.execute_script(FENCE_CELLS_JS)), timeout=max(args.timeout, 60))
    summary["fence_cells"] = cells
    ui.wait("the editor to close on the answer", lambda d: view()["editing"] == "false")
    summary["fence_summary"] = driver.find_element(By.CSS_SELECTOR, '[data-testid="fence-summary"]').text
    if f"v{before + 1}" not in summary["fence_summary"] or "polygon of 4" not in summary["fence_summary"]:
        raise Failure(f"fence summary `{summary['fence_summary']}`")
    timings["fence_applied"] = lap()

    # 5. The breach the test causes shows.
    ui.wait(f"{args.breach}'s row to read BREACH", lambda d: driver.execute_script(FENCE_CELLS_JS).get(args.breach) == "BREACH",
            timeout=150)
    ui.wait("a geofence_breach in the event log", lambda d: d.execute_script(
        "return document.querySelectorAll('[data-testid=\"event-log\"] li[data-type=\"geofence_breach\"]').length") > 0)
    timings["breach_shown"] = lap()
    ui.click("plan-fit")
    settled()
    if args.screenshot:
        driver.save_screenshot(args.screenshot)
        summary["screenshot"] = args.screenshot
    timings["screenshot"] = lap()
    # Console errors, but for the hole's tile: a 404 the page expects.
    errors = [e.get("message") for e in driver.get_log("browser")
              if e.get("level") == "SEVERE" and "/api/v1/map/tiles/" not in e.get("message", "")]
    summary["console_errors"] = errors
    if errors:
        raise Failure(f"console errors: {errors}")


def on_failure(driver, summary):
    summary["rows"] = driver.execute_script(FENCE_CELLS_JS)


if __name__ == "__main__":
    sys.exit(drive(parse_args(), run, on_failure))
