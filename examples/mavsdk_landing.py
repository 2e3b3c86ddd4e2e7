"""Land on the moving deck over MAVLink: MAVSDK flies, LANDING_TARGET (pymavlink) guides.

Connects to a PX4-style vehicle with MAVSDK, arms, starts offboard at the hold and descends onto
the deck with NED velocity setpoints, steering on the deck's absolute position in LOCAL_NED (the
``px4`` LANDING_TARGET profile) read with pymavlink from a second link, then reports each
touchdown. Nothing here imports ihrcf_env: point the two links at another vehicle and estimator
and it flies the same way. Needs ``pip install "ihrcf-env[mavlink]"``. Against the simulator:

    ihrcf-mavlink --level calm --camera-model projected --speed 4 --episodes 3 \\
        --out udpout:127.0.0.1:14540 --out udpout:127.0.0.1:14541
    python examples/mavsdk_landing.py --landings 3
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import time

os.environ["MAVLINK20"] = "1"  # pymavlink reads it on import: MAVLink 2 (LANDING_TARGET's position fields)

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.offboard import OffboardAsync, OffboardError, VelocityNedYaw  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import LandedState, TelemetryAsync  # noqa: E402
from pymavlink import mavutil  # noqa: E402

GAIN, MAX_XY = 1.0, 0.5  # horizontal: 1/s on the offset, m/s at most
ALIGNED, STALE = 0.12, 0.5  # m of offset to descend; s without a target before holding


class Targets:
    """The latest LANDING_TARGET (absolute NED, position_valid) and the vehicle's STATUSTEXTs."""

    def __init__(self, url: str) -> None:
        self.link = mavutil.mavlink_connection(url, dialect="common", source_system=246)
        self.ned: tuple[float, float, float] | None = None
        self.seen = -math.inf  # wall time of the last target
        self.texts: list[str] = []

    def poll(self) -> None:
        while (
            msg := self.link.recv_match(type=["LANDING_TARGET", "STATUSTEXT"], blocking=False)
        ) is not None:
            if msg.get_type() == "STATUSTEXT":
                self.texts.append(msg.text)
            elif msg.position_valid == 1 and msg.frame == mavutil.mavlink.MAV_FRAME_LOCAL_NED:
                self.ned, self.seen = (msg.x, msg.y, msg.z), time.monotonic()


def setpoint(
    target: tuple[float, float, float], pos: tuple[float, float, float], descent: float
) -> tuple[float, ...]:
    """NED velocity (m/s) towards the deck: close the horizontal offset, descend once aligned
    (slower over the last 0.6 m)."""
    dn, de = target[0] - pos[0], target[1] - pos[1]
    off = math.hypot(dn, de)
    scale = min(1.0, MAX_XY / max(GAIN * off, 1e-9))
    height = target[2] - pos[2]  # NED: the deck is below, further down
    vd = 0.0 if off > ALIGNED else (descent if height > 0.6 else 0.6 * descent)
    return GAIN * dn * scale, GAIN * de * scale, vd


async def land_once(
    tel: TelemetryAsync,
    action: ActionAsync,
    offboard: OffboardAsync,
    targets: Targets,
    args: argparse.Namespace,
) -> str:
    """Wait for a vehicle disarmed in the air, arm, offboard, descend; the touchdown's report."""
    while await tel.armed() or await tel.landed_state() != LandedState.IN_AIR:
        targets.poll()
        await asyncio.sleep(0.1)
    targets.texts.clear()
    targets.ned = None
    await action.arm()
    heading = (await tel.attitude_euler()).yaw_deg
    await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, heading))
    await offboard.start()
    t_end = time.monotonic() + args.timeout
    while time.monotonic() < t_end:
        targets.poll()
        if await tel.landed_state() == LandedState.ON_GROUND or any(
            t.startswith("episode end") for t in targets.texts
        ):
            break
        p = (await tel.position_velocity_ned()).position
        fresh = targets.ned is not None and time.monotonic() - targets.seen < STALE
        v = setpoint(targets.ned, (p.north_m, p.east_m, p.down_m), args.descent) if fresh else (0.0, 0.0, 0.0)
        await offboard.set_velocity_ned(VelocityNedYaw(*v, heading))
        await asyncio.sleep(1.0 / args.rate)
    try:
        await offboard.stop()
    except OffboardError:  # the vehicle left offboard by itself (landed: hold)
        pass
    for _ in range(20):  # the vehicle's report of the episode (STATUSTEXT), if it sends one
        targets.poll()
        done = [t for t in targets.texts if t.startswith("episode end")]
        if done:
            return done[-1]
        await asyncio.sleep(0.1)
    return f"landed state {await tel.landed_state()}"


async def run(args: argparse.Namespace) -> int:
    targets = Targets(args.targets)
    async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
        await sdk.add_any_connection(args.connect)
        system = await sdk.first_autopilot(timeout_s=args.connect_timeout)
        if system is None:
            print(f"no vehicle on {args.connect} within {args.connect_timeout} s")
            return 1
        tel, action, offboard = TelemetryAsync(system), ActionAsync(system), OffboardAsync(system)
        ok = 0
        for i in range(args.landings):
            report = await land_once(tel, action, offboard, targets, args)
            ok += "success" in report
            print(f"touchdown {i + 1}: {report}", flush=True)
    print(f"landed {ok}/{args.landings}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--connect", default="udpin://0.0.0.0:14540", help="MAVSDK connection (default: %(default)s)"
    )
    ap.add_argument(
        "--targets",
        default="udpin:0.0.0.0:14541",
        help="pymavlink link of LANDING_TARGET (default: %(default)s)",
    )
    ap.add_argument("--landings", type=int, default=1, help="landings, one per episode (default: 1)")
    ap.add_argument("--descent", type=float, default=0.35, help="descent speed, m/s (default: 0.35)")
    ap.add_argument("--rate", type=float, default=40.0, help="setpoints per second, wall clock (default: 40)")
    ap.add_argument("--timeout", type=float, default=60.0, help="s of wall time per landing (default: 60)")
    ap.add_argument("--connect-timeout", type=float, default=30.0, help="s to find the vehicle (default: 30)")
    return asyncio.run(run(ap.parse_args()))


if __name__ == "__main__":
    raise SystemExit(main())
