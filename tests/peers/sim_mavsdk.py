#!/usr/bin/env python3
"""Fly skein's simulator (or PX4 SITL) with MAVSDK (the `mavsdk` 4.x native binding, which
bundles the MAVSDK C++ library).

MAVSDK listens where the vehicle sends (``udpin://0.0.0.0:PORT``, the vehicle's target
port, 14540+i for PX4 SITL instance i), waits until its health says global position,
home position and armable are OK, arms, takes off, starts OFFBOARD with
``set_position_ned`` (after sending the initial setpoint MAVSDK requires), reaches the
target within 0.5 m, lands and waits for ``armed == False``.

With ``--documented-start`` it flies MAVSDK's documented offboard start instead: arm on
the ground, set ONE setpoint, ``offboard.start()``, then fly to the target (PX4 v1.16
accepts OFFBOARD as soon as one setpoint younger than COM_OF_LOSS_T has arrived).

Every step has a deadline inside the global ``--timeout``. Exit code 0 only on success;
the last line printed is a JSON summary.
"""

import argparse
import asyncio
import json
import math
import os
import sys
import time

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.offboard import PositionNedYaw

TARGET_NED = (3.0, 2.0, -5.0)


class Failure(Exception):
    pass


class Run:
    def __init__(self, timeout):
        self.deadline = time.monotonic() + timeout
        self.steps = []

    def remaining(self):
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise Failure("global timeout")
        return left

    async def step(self, name, coro, timeout):
        t0 = time.monotonic()
        try:
            result = await asyncio.wait_for(coro, min(timeout, self.remaining()))
        except asyncio.TimeoutError:
            self.steps.append({"step": name, "ok": False, "s": round(time.monotonic() - t0, 2)})
            raise Failure(f"{name}: timed out") from None
        except Failure:
            raise
        except Exception as e:  # MAVSDK errors (ActionError, OffboardError …)
            self.steps.append({"step": name, "ok": False, "error": str(e)})
            raise Failure(f"{name}: {type(e).__name__}: {e}") from None
        self.steps.append({"step": name, "ok": True, "s": round(time.monotonic() - t0, 2)})
        return result


async def first(gen, pred):
    """First value of an async generator satisfying `pred`."""
    try:
        async for value in gen:
            if pred(value):
                return value
    finally:
        await gen.aclose()
    raise Failure("subscription ended")


async def fly(port, run, documented_start=False):
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as mavsdk:
        await run.step("connect", mavsdk.add_any_connection(f"udpin://0.0.0.0:{port}"), 10)
        system = await run.step("autopilot discovered", mavsdk.first_autopilot(timeout_s=20.0), 25)
        if system is None:
            raise Failure("no autopilot found")
        telemetry = TelemetryAsync(system)
        action = ActionAsync(system)
        offboard = OffboardAsync(system)

        health = await run.step(
            "health: global position, home, armable",
            first(
                telemetry.subscribe_health(),
                lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
            ),
            30,
        )
        home = await run.step("home position", telemetry.home(), 10)

        await run.step("arm", action.arm(), 10)
        n, e, d = TARGET_NED
        if documented_start:
            # MAVSDK's documented start: one setpoint, then start offboard right away.
            await run.step(
                "one setpoint", offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0)), 5
            )
            await run.step("offboard start", offboard.start(), 10)
            await run.step(
                "flight mode OFFBOARD",
                first(telemetry.subscribe_flight_mode(), lambda m: m.name == "OFFBOARD"),
                5,
            )
            return await fly_to_target_and_land(run, action, offboard, telemetry, health, home)
        await run.step("takeoff", action.takeoff(), 10)
        await run.step("in air", first(telemetry.subscribe_in_air(), lambda a: a), 15)
        takeoff_alt = await run.step("takeoff altitude", action.get_takeoff_altitude(), 10)
        await run.step(
            "reached takeoff altitude",
            first(
                telemetry.subscribe_position(),
                lambda p: p.relative_altitude_m > 0.8 * takeoff_alt,
            ),
            20,
        )

        # MAVSDK requires a setpoint before starting offboard and streams at 20 Hz once
        # started; PX4 wants the stream running for > 1 s before it accepts OFFBOARD, so
        # send the hold setpoint at 20 Hz for 1.3 s first.
        hold = PositionNedYaw(0.0, 0.0, -takeoff_alt, 0.0)
        prestream_until = time.monotonic() + 1.3
        while time.monotonic() < prestream_until:
            await run.step("pre-stream setpoint", offboard.set_position_ned(hold), 5)
            await asyncio.sleep(0.05)
        await run.step("offboard start", offboard.start(), 10)
        await run.step(
            "flight mode OFFBOARD",
            first(telemetry.subscribe_flight_mode(), lambda m: m.name == "OFFBOARD"),
            5,
        )
        return await fly_to_target_and_land(run, action, offboard, telemetry, health, home)


async def fly_to_target_and_land(run, action, offboard, telemetry, health, home):
    n, e, d = TARGET_NED
    await run.step("set_position_ned", offboard.set_position_ned(PositionNedYaw(n, e, d, 90.0)), 5)
    reached = await run.step(
        "target reached within 0.5 m",
        first(
            telemetry.subscribe_position_velocity_ned(),
            lambda pv: math.dist(
                (pv.position.north_m, pv.position.east_m, pv.position.down_m), TARGET_NED
            )
            < 0.5,
        ),
        30,
    )

    await run.step("land", action.land(), 10)
    await run.step("disarmed", first(telemetry.subscribe_armed(), lambda a: not a), 60)
    return {
        "health": {
            "global_position_ok": health.is_global_position_ok,
            "home_position_ok": health.is_home_position_ok,
            "armable": health.is_armable,
        },
        "home": [home.latitude_deg, home.longitude_deg, home.absolute_altitude_m],
        "reached_ned": [
            round(reached.position.north_m, 2),
            round(reached.position.east_m, 2),
            round(reached.position.down_m, 2),
        ],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--port", type=int, required=True, help="UDP port the vehicle sends to (listen here)")
    ap.add_argument("--timeout", type=float, default=180.0, help="overall deadline, seconds")
    ap.add_argument(
        "--documented-start",
        action="store_true",
        help="arm, one setpoint, offboard.start() (MAVSDK's documented sequence)",
    )
    args = ap.parse_args()

    run = Run(args.timeout)
    ok, error, details = True, None, {}
    try:
        details = asyncio.run(asyncio.wait_for(fly(args.port, run, args.documented_start), args.timeout + 5))
    except Failure as e:
        ok, error = False, str(e)
    except asyncio.TimeoutError:
        ok, error = False, "global timeout"
    except Exception as e:
        ok, error = False, f"{type(e).__name__}: {e}"
    print(json.dumps({"ok": ok, "error": error, "steps": run.steps, **(details or {})}))
    sys.stdout.flush()
    # MAVSDK's worker threads must not keep a failed run alive past its deadline.
    os._exit(0 if ok else 1)


if __name__ == "__main__":
    main()
