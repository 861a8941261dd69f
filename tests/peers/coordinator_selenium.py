#!/usr/bin/env python3
"""Drives two coordinator candidates' dashboards (`skein coordinator`) in real headless
Chromium:

1. the standby's dashboard shows its role as standby and a banner naming the active
   coordinator, with a link to the active one's dashboard;
2. the active one's dashboard shows it as active, with its epoch, and no banner;
3. no severe error in the browser console of either.

Prints one JSON summary line; exits 0 only on success.

    python3 tests/peers/coordinator_selenium.py --standby http://127.0.0.1:P1/ \
        --active http://127.0.0.1:P2/ --active-id gcs-a
"""

import argparse
import sys


from dashboard_selenium import Dashboard, Failure, add_browser_args, drive

ROLE_JS = """
const b = document.querySelector('[data-testid="coordinator-role"]');
const s = document.querySelector('[data-testid="standby-banner"]');
const a = document.querySelector('[data-testid="coordinator-active-link"]');
return {role: b.hidden ? null : b.dataset.role, badge: b.textContent, epoch: b.dataset.epoch,
        dds: b.dataset.dds || null,
        banner: s.hidden ? null : s.textContent, active: s.dataset.active || null,
        link: a ? a.getAttribute('href') : null};
"""


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--standby", required=True)
    p.add_argument("--active", required=True)
    p.add_argument("--active-id", required=True)
    p.add_argument("--timeout", type=float, default=30.0)
    p.add_argument("--dds", default="open", choices=["open", "secured"],
                   help="what the badge must say of the swarm link")
    add_browser_args(p)
    return p.parse_args()


def severe(driver):
    return [e.get("message") for e in driver.get_log("browser") if e.get("level") == "SEVERE"]


def run(args, driver, summary):
    ui = Dashboard(driver, args.timeout)
    active_base = args.active.rstrip("/")

    ui.open(args.standby)

    def standby_shown(_):
        ui.last = driver.execute_script(ROLE_JS)
        r = ui.last
        return r["role"] == "standby" and r["active"] == args.active_id and r["link"] == active_base + "/"
    ui.wait("the standby's role and banner naming the active coordinator", standby_shown)
    summary["standby"] = ui.last
    if args.active_id not in (ui.last["banner"] or ""):
        raise Failure(f"the banner does not name {args.active_id}: {ui.last}")
    errors = severe(driver)
    if errors:
        raise Failure(f"console errors on the standby: {errors}")

    driver.get(args.active)

    def active_shown(_):
        ui.last = driver.execute_script(ROLE_JS)
        return (ui.last["role"] == "active" and ui.last["banner"] is None
                and ui.last["dds"] == args.dds and f"DDS {args.dds}" in ui.last["badge"])
    ui.wait(f"the active coordinator's role, no banner, the DDS link {args.dds}", active_shown)
    summary["active"] = ui.last
    errors = severe(driver)
    if errors:
        raise Failure(f"console errors on the active one: {errors}")


def main():
    return drive(parse_args(), run)


if __name__ == "__main__":
    sys.exit(main())
