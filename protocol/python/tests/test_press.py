"""A Python device against a real Sinew server: press the pad and feel it. Hover (no force), press 1, 3 and 5
mm into the surface (a force along +z that grows with depth), lift (no force again).

    python3 protocol/python/tests/test_press.py --connect tcp/127.0.0.1:7447 [--scene pad --device left]

The server must run the shipped pad (worlds/pad.toml): the left probe is a 4 mm sphere whose device origin sits
on the pad's surface, so the sphere touches it at z = 4 mm (device frame).
"""

import argparse
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from sinew_client.device import Device  # noqa: E402

RADIUS_MM = 4.0


def hold(device, z_mm, seconds, measure_last_s):
    """Publish poses at about 1 kHz at height z for `seconds`; the mean force over the last part."""
    samples = []
    start = time.monotonic()
    next_at = start
    while True:
        now = time.monotonic()
        if now - start >= seconds:
            break
        device.publish_pose([0.0, 0.0, z_mm])
        if now - start >= seconds - measure_last_s:
            samples.append(device.safe_force())
        next_at += 0.001
        delay = next_at - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    n = max(1, len(samples))
    return [sum(s[i] for s in samples) / n for i in range(3)]


def norm(v):
    return sum(c * c for c in v) ** 0.5


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447")
    parser.add_argument("--scene", default="pad")
    parser.add_argument("--device", default="left")
    args = parser.parse_args()
    device = Device(args.scene, args.device, connect=[args.connect], max_force_n=3.3, device_model="python-test")
    device.open()
    try:
        time.sleep(0.3)  # the hello reaches the server before the first pose
        hover = hold(device, 10.0, 1.0, 0.3)
        assert device.latest_force() is not None, "no force command arrived: is the server running the pad?"
        print(f"hover at 10 mm: force {norm(hover):.3f} N")
        assert norm(hover) < 0.05, f"a force out of contact: {hover}"
        pressed = []
        for depth in (1.0, 3.0, 5.0):
            f = hold(device, RADIUS_MM - depth, 0.8, 0.3)
            print(f"pressed {depth} mm: force {f[0]:+.3f} {f[1]:+.3f} {f[2]:+.3f} N")
            assert f[2] > 0.9 * norm(f), f"the force is not along +z: {f}"
            pressed.append(f[2])
        assert 0.05 < pressed[0] < pressed[1] < pressed[2], f"the force does not grow with depth: {pressed}"
        lifted = hold(device, 10.0, 1.0, 0.3)
        print(f"lifted to 10 mm: force {norm(lifted):.3f} N; round trip {device.round_trip_us} us")
        assert norm(lifted) < 0.05, f"a force after lifting: {lifted}"
        assert 0 < device.round_trip_us < 100_000, device.round_trip_us
        assert device.refused["malformed"] == 0, device.refused
    finally:
        device.close()
    print("test_press: the pad pushes back along +z, harder with depth, and lets go")


if __name__ == "__main__":
    main()
