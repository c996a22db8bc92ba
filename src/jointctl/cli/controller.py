"""``jointctl controller``: a simulated industrial robot controller speaking simple_message."""

from __future__ import annotations

import argparse

from jointctl.cli.common import live_scenario, live_target_arguments


def add_parsers(sub) -> None:
    controller = sub.add_parser("controller", help="a simulated industrial robot controller: the robot in MuJoCo with "
                                                   "its own interpolator, speaking simple_message")
    live_target_arguments(controller)  # controllers: the robot's servo file by default
    controller.add_argument("--host", default="0.0.0.0", help="address to listen on (default 0.0.0.0, as a "
                                                              "controller cabinet does)")
    controller.add_argument("--motion-port", type=int, default=11000, help="motion port (default 11000; 0: any free)")
    controller.add_argument("--state-port", type=int, default=11002, help="state port (default 11002; 0: any free)")
    controller.add_argument("--big-endian", action="store_true", help="speak big-endian (for the _bswap drivers)")
    controller.add_argument("--state-rate-hz", type=float, default=50.0,
                            help="joint state and status reports per second (default 50)")
    controller.set_defaults(handler=_controller)


def _controller(args: argparse.Namespace) -> int:
    import signal

    from jointctl.industrial_controller.controller import SimulatedController

    scenario = live_scenario(args)
    controller = SimulatedController(scenario, host=args.host, motion_port=args.motion_port,
                                     state_port=args.state_port, big_endian=args.big_endian,
                                     state_rate_hz=args.state_rate_hz, speed=args.speed)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: controller.stop())
    order = "big-endian" if args.big_endian else "little-endian"
    print(f"jointctl controller: {scenario.robot.name} (joints "
          f"{', '.join(controller.joint_names)}) on {args.host}, motion port {controller.motion_port}, "
          f"state port {controller.state_port}, {order}", flush=True)
    try:
        controller.run()
    finally:
        controller.close()
    return 0
