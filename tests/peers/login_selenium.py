#!/usr/bin/env python3
"""Logs in to a skein that requires tokens, in real headless Chromium:

1. the page shows the login (the API answered 401); a wrong token is refused with a message;
2. the viewer token: the page shows `watch` / `viewer`, the stream connects (`?token=`),
   the vehicle rows arrive, and the swarm commands are hidden;
3. log out: the login again; the operator token: the swarm commands are shown.

Prints one JSON summary line; exits 0 only on success.

    python3 tests/peers/login_selenium.py --url URL --viewer-token T --operator-token T
"""

import argparse
import json
import sys

from selenium.common.exceptions import (NoSuchElementException, StaleElementReferenceException,
                                        TimeoutException, WebDriverException)
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from dashboard_selenium import add_browser_args, make_driver


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", required=True)
    p.add_argument("--viewer-token", required=True)
    p.add_argument("--operator-token", required=True)
    p.add_argument("--timeout", type=float, default=30.0)
    add_browser_args(p)
    return p.parse_args()


def main():
    args = parse_args()
    driver = make_driver(args)
    steps = []

    def wait(what, cond):
        try:
            # The page reloads after a login: elements found before it go stale.
            return WebDriverWait(driver, args.timeout, poll_frequency=0.1,
                                 ignored_exceptions=(NoSuchElementException, StaleElementReferenceException)
                                 ).until(lambda d: cond())
        except TimeoutException:
            raise SystemExit(json.dumps({"ok": False, "failed": what, "steps": steps}))

    by_id = lambda i: driver.find_element(By.ID, i)
    swarm_cmds = lambda: driver.find_element(By.CSS_SELECTOR, '[aria-label="Swarm commands"]')

    def login(token):
        field = by_id("login-token")
        field.clear()
        field.send_keys(token)
        driver.find_element(By.CSS_SELECTOR, '[data-testid="login-submit"]').click()

    try:
        driver.get(args.url)
        wait("login shown", lambda: by_id("login").is_displayed())
        steps.append("login shown")
        login("not-a-token")
        wait("wrong token refused", lambda: by_id("login-error").text.strip() != "")
        steps.append("wrong token refused: " + by_id("login-error").text.strip())

        login(args.viewer_token)
        wait("viewer logged in", lambda: by_id("auth-who").is_displayed()
             and by_id("auth-name").text == "watch" and by_id("auth-role").text == "viewer")
        wait("stream connected", lambda: by_id("connection").get_attribute("data-state") == "connected")
        wait("vehicle rows", lambda: len(driver.find_elements(By.CSS_SELECTOR, "tr[data-vehicle-id]")) >= 1)
        wait("swarm commands hidden for a viewer", lambda: not swarm_cmds().is_displayed())
        if by_id("login").is_displayed():
            raise SystemExit(json.dumps({"ok": False, "failed": "login still shown", "steps": steps}))
        steps.append("viewer: name, role, stream, rows, no swarm commands")

        driver.find_element(By.CSS_SELECTOR, '[data-testid="auth-logout"]').click()
        wait("login after logout", lambda: by_id("login").is_displayed())
        login(args.operator_token)
        wait("operator logged in", lambda: by_id("auth-role").text == "operator")
        wait("swarm commands shown for an operator", lambda: swarm_cmds().is_displayed())
        steps.append("operator: swarm commands shown")
    except WebDriverException as e:
        print(json.dumps({"ok": False, "error": str(e).splitlines()[0], "steps": steps}))
        return 1
    finally:
        driver.quit()
    print(json.dumps({"ok": True, "steps": steps}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
