"""``static/metawear/protocol.js`` in Chromium against the bytes the tests' twin (``metawear_frames.py``) makes from
the simulator.

* Encoder: the commands for the protocol's set-up (acc and gyro 100 Hz, magnetometer 20 Hz, ±16 g, ±2000 °/s)
  are the bytes the public description and the Bosch datasheets give (ACC_CONF 0x28 = 100 Hz normal filter,
  ACC_RANGE 0x0c = ±16 g on a BMI160, 0x03 on a BMI270; GYR_RANGE 0 = ±2000 °/s; BMM150 20 Hz = 5, 9/15
  repetitions = [4, 14]); a rate or range the sensor lacks is refused.
* Decoder: a simulated task of both sensors (thigh and shank of :func:`app.pipeline.demo.simulate_session`),
  quantised and framed by the twin, decodes to exactly the twin's counts over the sensitivities, and to the
  simulator's true values within half a count; wrong lengths are refused; module info and battery answers read.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimators.physics import STANDARD_GRAVITY_M_S2
from metawear_frames import LSB, board_units, counts, sensor_notifications

IMPORT = "const p = await import('/metawear/protocol.js');"


@pytest.fixture(scope="module")
def session():
    from app.pipeline.demo import simulate_session

    return simulate_session(seed=3, side="right", n_cycles=2)


def _hex(commands) -> list[str]:
    return [bytes(c).hex() for c in commands]


def test_the_protocol_setup_commands(static_page):
    out = static_page.evaluate(f"""async () => {{ {IMPORT}
        const hex = (cs) => cs.map((c) => Array.from(c, (b) => b.toString(16).padStart(2, '0')).join(''));
        return {{bmi160: hex(p.configure(p.PROTOCOL_CONFIG, {{acc: 'BMI160', gyr: 'BMI160'}})),
                bmi270: hex(p.configure(p.PROTOCOL_CONFIG, {{acc: 'BMI270', gyr: 'BMI270'}})),
                start: hex(p.startStreaming()), startSingle: hex(p.startStreaming({{packed: false}})),
                stop: hex(p.stopStreaming()), battery: hex([p.readBattery()]),
                info: hex([p.readModuleInfo(p.MODULE.ACCELEROMETER)]),
                service: p.SERVICE, command: p.COMMAND_CHAR, notify: p.NOTIFY_CHAR}}; }}""")
    assert out["bmi160"] == ["0303280c", "13032800", "150100", "1504040e", "150305"]
    assert out["bmi270"][0] == "0303a803" and out["bmi270"][1:] == out["bmi160"][1:]
    # subscribe to the (packed) data register, enable the data interrupt, power on: acc, gyro, magnetometer
    assert out["start"] == ["031c01", "03020100", "030101", "130701", "13020100", "130101",
                            "150501", "15020100", "150101"]
    assert out["startSingle"][0] == "030401" and out["startSingle"][3] == "130501"
    assert out["stop"][:4] == ["030100", "03020001", "030400", "031c00"] and len(out["stop"]) == 12
    assert out["battery"] == ["118c"] and out["info"] == ["0380"]
    assert out["service"] == "326a9000-85cb-9195-d9dd-464cfbbae75a"
    assert out["command"].startswith("326a9001-") and out["notify"].startswith("326a9006-")


@pytest.mark.parametrize("change, words", [({"accHz": 120}, "accelerometer rate"), ({"gyrRangeDps": 4000}, "gyroscope range"),
                                           ({"magHz": 100}, "magnetometer rate"), ({"accRangeG": 3}, "accelerometer range")])
def test_a_setting_the_sensor_lacks_is_refused(static_page, change, words):
    message = static_page.evaluate(f"""async (change) => {{ {IMPORT}
        try {{ p.configure({{...p.PROTOCOL_CONFIG, ...change}}); p.sensitivities({{...p.PROTOCOL_CONFIG, ...change}}); }}
        catch (e) {{ return e instanceof p.ProtocolError ? e.message : 'other: ' + e; }}
        return null; }}""", change)
    assert message is not None and words in message


def test_simulated_streams_decode_to_their_counts_and_truth(static_page, session):
    for segment in ("thigh", "shank"):
        streams = session.recordings[(segment, "task")]
        frames = sensor_notifications(streams)
        decoded = static_page.evaluate(f"""async (frames) => {{ {IMPORT}
            const out = {{acc: [], gyr: [], mag: []}};
            for (const f of frames) {{
                const bytes = Uint8Array.from(f.match(/../g), (x) => parseInt(x, 16));
                const d = p.decode(new DataView(bytes.buffer));
                out[d.kind].push(...d.values);
            }}
            return out; }}""", [n.payload.hex() for n in frames])
        for kind in ("acc", "gyr", "mag"):
            t_s, values = streams[kind]
            per = 1 if kind == "mag" else 3
            n = len(t_s) // per * per
            got = np.asarray(decoded[kind])
            assert got.shape == (n, 3), (segment, kind)
            # exactly the counts the twin sent, over the sensitivity
            np.testing.assert_array_equal(got, counts(kind, values[:n]) / LSB[kind])
            # and the simulator's truth within half a count (no sample saturates in a step-up)
            np.testing.assert_array_less(np.abs(got - board_units(kind, values[:n])), 0.5 / LSB[kind] + 1e-12)
    # the units are g, °/s and µT: a still sensor's acceleration norm is one g
    still = np.asarray(decoded["acc"][:20])
    assert abs(np.linalg.norm(still, axis=1).mean() - 9.81 / STANDARD_GRAVITY_M_S2) < 0.05


def test_answers_and_bad_packets(static_page):
    out = static_page.evaluate(f"""async () => {{ {IMPORT}
        const d = (...b) => {{ try {{ return p.decode(Uint8Array.from(b)); }}
                               catch (e) {{ return {{error: e instanceof p.ProtocolError, message: e.message}}; }} }};
        return {{info: d(0x03, 0x80, 0x01, 0x02), gyroInfo: d(0x13, 0x80, 0x01, 0x00),
                battery: d(0x11, 0x8c, 87, 0x1c, 0x0f), short: d(0x03, 0x04, 1, 2, 3), tiny: d(0x03),
                other: d(0x01, 0x01, 0x01), chips: p.chipsOf(d(0x03, 0x80, 4, 0), d(0x13, 0x80, 1, 0)),
                oldChip: (() => {{ try {{ p.chipsOf(d(0x03, 0x80, 0, 0), d(0x13, 0x80, 0, 0)); }}
                                  catch (e) {{ return e.message; }} }})(),
                single: d(0x15, 0x05, 0x10, 0x00, 0xf0, 0xff, 0x00, 0x80)}}; }}""")
    assert out["info"] == {"kind": "module", "module": 3, "implementation": 1, "revision": 2}
    assert out["battery"] == {"kind": "battery", "chargePercent": 87, "voltageMv": 0x0F1C}
    assert out["short"]["error"] and "expected 8" in out["short"]["message"]
    assert out["tiny"]["error"] and out["other"] == {"kind": "other", "module": 1, "register": 1}
    assert out["chips"] == {"acc": "BMI270", "gyr": "BMI270"}
    assert "implementation 0" in out["oldChip"]
    # little-endian int16 over 16 LSB/µT: 0x0010 = 1 µT, 0xfff0 = -1 µT, 0x8000 = -2048 µT
    assert out["single"] == {"kind": "mag", "values": [[1.0, -1.0, -2048.0]]}
