"""The MetaWear notifications a MetaMotion sensor would send for a simulated recording (the tests' Python twin of
``static/metawear/protocol.js``, written independently from the same public description).

A simulated stream (:func:`app.pipeline.demo.simulate_session`: acc m/s², gyr rad/s, mag µT) is converted to the
board's units (g, °/s, µT), quantised to int16 counts at the protocol's ranges (±16 g: 2048 LSB/g; ±2000 °/s:
16.4 LSB/(°/s); BMM150: 16 LSB/µT) and framed as ``[module, register, int16 LE …]`` with the board's registers
(MbientLab's register maps): a MetaMotion R (BMI160) sends the accelerometer (module 0x03) on its packed register
0x1c and the gyroscope (0x13) on 0x07, three samples per notification; a MetaMotion S (BMI270) sends both on
register 0x05, also packed; the magnetometer (0x15) is register 0x05, one sample, on both.  Each notification leaves the sensor when its last sample is taken; that true time is its
arrival time here (no air latency).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from estimators.physics import STANDARD_GRAVITY_M_S2

#: LSB per board unit at the protocol's ranges
LSB = {"acc": 32768 / 16, "gyr": 16.4, "mag": 16.0}
#: per chip: (module, register, samples per notification)
FRAMES = {
    "BMI160": {"acc": (0x03, 0x1C, 3), "gyr": (0x13, 0x07, 3), "mag": (0x15, 0x05, 1)},
    "BMI270": {"acc": (0x03, 0x05, 3), "gyr": (0x13, 0x05, 3), "mag": (0x15, 0x05, 1)},
}
#: the module info answers' implementation byte of each chip (accelerometer, gyroscope)
IMPLEMENTATION = {"BMI160": (1, 0), "BMI270": (4, 1)}
#: the LED module (0x02): play (register 1, [1]) and stop clearing the patterns (register 2, [1])
LED_PLAY = bytes((0x02, 0x01, 0x01))
LED_STOP_AND_CLEAR = bytes((0x02, 0x02, 0x01))
LED_COLOURS = {"green": 0, "red": 1, "blue": 2}


def led_pattern(colour: str, high: int, low: int, rise_ms: int, high_ms: int, fall_ms: int, pulse_ms: int,
                delay_ms: int, repeat: int) -> bytes:
    """The LED module's pattern command (register 3) of one colour: colour, 0x02, the two intensities (0–31), five
    uint16 LE times in ms (rise, high, fall, pulse duration, delay) and the repeat count."""
    return bytes((0x02, 0x03, LED_COLOURS[colour], 0x02)) + struct.pack(
        "<BBHHHHHB", high, low, rise_ms, high_ms, fall_ms, pulse_ms, delay_ms, repeat)


def board_units(kind: str, values_si: np.ndarray) -> np.ndarray:
    """SI values (m/s², rad/s, µT) → the board's units (g, °/s, µT)."""
    if kind == "acc":
        return values_si / STANDARD_GRAVITY_M_S2
    if kind == "gyr":
        return np.rad2deg(values_si)
    return values_si


def counts(kind: str, values_si: np.ndarray) -> np.ndarray:
    """The int16 counts the sensor reports for ``values_si`` (rounded, clipped to the int16 range)."""
    return np.clip(np.round(board_units(kind, values_si) * LSB[kind]), -32768, 32767).astype(np.int16)


@dataclass(frozen=True)
class Notification:
    arrival_s: float
    kind: str
    payload: bytes


def notifications(kind: str, t_s: np.ndarray, values_si: np.ndarray, chip: str = "BMI160") -> list[Notification]:
    """The notifications of one stream of a board with ``chip``; a last incomplete packed group is not sent (the
    board waits for it)."""
    module, register, per = FRAMES[chip][kind]
    raw = counts(kind, values_si)
    out = []
    for start in range(0, len(raw) - per + 1, per):
        body = b"".join(struct.pack("<hhh", *map(int, raw[k])) for k in range(start, start + per))
        out.append(Notification(float(t_s[start + per - 1]), kind, bytes((module, register)) + body))
    return out


def sensor_notifications(streams: dict, chip: str = "BMI160") -> list[Notification]:
    """All notifications of one sensor's recording (``{kind: (t_s, values)}``) in arrival order."""
    every = [n for kind in ("acc", "gyr", "mag") for n in notifications(kind, *streams[kind], chip=chip)]
    return sorted(every, key=lambda n: n.arrival_s)
