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
from metawear_frames import LED_PLAY, LED_STOP_AND_CLEAR, LSB, board_units, counts, led_pattern, sensor_notifications

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
                start: hex(p.startStreaming()), startSingle: hex(p.startStreaming({{...p.BMI160_BOARD, packed: {{acc: false, gyr: false}}}})),
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


@pytest.mark.parametrize("chip", ["BMI160", "BMI270"])
def test_simulated_streams_decode_to_their_counts_and_truth(static_page, session, chip):
    """A MetaMotion R (BMI160) and a MetaMotion S (BMI270), each decoded with its own register table."""
    for segment in ("thigh", "shank"):
        streams = session.recordings[(segment, "task")]
        frames = sensor_notifications(streams, chip)
        decoded = static_page.evaluate(f"""async ([frames, chip]) => {{ {IMPORT}
            const chips = {{acc: chip, gyr: chip, packed: {{acc: true, gyr: true}}}};
            const out = {{acc: [], gyr: [], mag: []}};
            for (const f of frames) {{
                const bytes = Uint8Array.from(f.match(/../g), (x) => parseInt(x, 16));
                const d = p.decode(new DataView(bytes.buffer), p.sensitivities(), chips);
                out[d.kind].push(...d.values);
            }}
            return out; }}""", [[n.payload.hex() for n in frames], chip])
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
    # revision 0: a module too old to pack samples
    assert out["chips"] == {"acc": "BMI270", "gyr": "BMI270", "packed": {"acc": False, "gyr": False}}
    assert "implementation 0" in out["oldChip"]
    # little-endian int16 over 16 LSB/µT: 0x0010 = 1 µT, 0xfff0 = -1 µT, 0x8000 = -2048 µT
    assert out["single"] == {"kind": "mag", "values": [[1.0, -1.0, -2048.0]]}


def test_a_metamotion_s_streams_on_its_own_registers(static_page):
    """The BMI270's data registers (MbientLab's register map: acc and gyro packed on 0x05, single on 0x04), and
    the modules' revision choosing packed or single samples; a BMI270's packed gyroscope packet (0x13 0x05, 20
    bytes) read with a BMI160's table is a bad packet (there 0x05 is the single sample), not three samples."""
    out = static_page.evaluate(f"""async () => {{ {IMPORT}
        const hex = (cs) => cs.map((c) => Array.from(c, (b) => b.toString(16).padStart(2, '0')).join(''));
        const s = p.chipsOf({{implementation: 4, revision: 1}}, {{implementation: 1, revision: 1}});
        const old = p.chipsOf({{implementation: 4, revision: 0}}, {{implementation: 1, revision: 0}});
        const packet = new Uint8Array(20); packet[0] = 0x13; packet[1] = 0x05; packet[2] = 164;
        let misread = null;
        try {{ p.decode(packet); }} catch (e) {{ misread = e instanceof p.ProtocolError; }}
        return {{chips: s, start: hex(p.startStreaming(s)), startOld: hex(p.startStreaming(old)),
                stop: hex(p.stopStreaming(s)), gyro: p.decode(packet, p.sensitivities(), s), misread}}; }}""")
    assert out["chips"] == {"acc": "BMI270", "gyr": "BMI270", "packed": {"acc": True, "gyr": True}}
    assert out["start"] == ["030501", "03020100", "030101", "130501", "13020100", "130101",
                            "150501", "15020100", "150101"]
    assert out["startOld"][0] == "030401" and out["startOld"][3] == "130401"
    assert {"030400", "030500", "130400", "130500"} <= set(out["stop"])
    assert out["gyro"] == {"kind": "gyr", "values": [[10.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]}
    assert out["misread"] is True


def test_bluetooth_errors_are_said_in_three_languages(static_page):
    """Web Bluetooth's DOMException names map to the recorder's codes, each a sentence in es/en/pt (the browser's
    own messages are English only)."""
    import json
    from pathlib import Path

    out = static_page.evaluate("""async () => { const d = await import('/metawear/device.js');
        return {table: d.BLUETOOTH_ERRORS, network: d.bluetoothErrorCode(new DOMException('x', 'NetworkError')),
                other: d.bluetoothErrorCode(new Error('x'))}; }""")
    assert out["network"] == "bt_network" and out["other"] is None
    static = Path(__file__).resolve().parents[2] / "static" / "i18n"
    for lang in ("es", "en", "pt"):
        table = json.loads((static / f"{lang}.json").read_text(encoding="utf-8"))
        assert all(table.get(f"record.error.{code}") for code in out["table"].values()), lang


def test_the_led_blink_commands(static_page):
    """The blink that tells the sensors apart: stop and clear, the pattern of one colour (full brightness 200 ms of
    every 500 ms, six times), play; the twin's bytes from the same public description.  Bad input is refused."""
    out = static_page.evaluate(f"""async () => {{ {IMPORT}
        const hex = (cs) => cs.map((c) => Array.from(c, (b) => b.toString(16).padStart(2, '0')).join(''));
        const refused = (f) => {{ try {{ f(); return null; }} catch (e) {{ return e.message; }} }};
        return {{green: hex(p.blinkLed()), red: hex(p.blinkLed('red')), stop: hex([p.stopLed()]),
                 slow: hex(p.blinkLed('blue', {{...p.BLINK, highMs: 1000, pulseMs: 2000, repeat: 255}})),
                 colour: refused(() => p.blinkLed('purple')), bright: refused(() => p.blinkLed('green', {{...p.BLINK, high: 32}})),
                 long: refused(() => p.blinkLed('green', {{...p.BLINK, pulseMs: 70000}}))}}; }}""")
    blink = led_pattern("green", 31, 0, 0, 200, 0, 500, 0, 6)
    assert out["green"] == _hex([LED_STOP_AND_CLEAR, blink, LED_PLAY])
    # module, register, colour, 0x02 | high, low | rise, high, fall, pulse, delay (ms, uint16 LE) | repeat
    assert blink.hex() == "02030002" "1f00" "0000" "c800" "0000" "f401" "0000" "06"
    assert out["red"][1] == led_pattern("red", 31, 0, 0, 200, 0, 500, 0, 6).hex()
    assert out["slow"][1] == led_pattern("blue", 31, 0, 0, 1000, 0, 2000, 0, 255).hex()
    assert out["stop"] == [LED_STOP_AND_CLEAR.hex()]
    assert "purple" in out["colour"] and "32" in out["bright"] and "70000" in out["long"]


def test_a_failed_write_does_not_block_the_later_ones(static_page):
    """One write the board refuses (a blink while the link is busy) fails for its caller only: the next writes on
    that sensor (configure and start, a reconnection's stop) still go out, in order.  The GATT characteristic is
    the browser's boundary, played here by an object whose first write rejects as Web Bluetooth's do."""
    out = static_page.evaluate("""async () => { const d = await import('/metawear/device.js');
        const device = { name: 'MetaWear', id: 'x', addEventListener() {}, gatt: { connected: true } };
        const sensor = new d.MetaWearSensor(device);
        const written = [];
        let calls = 0;
        sensor.command = { async writeValueWithResponse(c) {
            calls += 1;
            if (calls === 1) throw new DOMException('GATT operation failed', 'NetworkError');
            written.push(Array.from(c)); } };
        const first = await sensor.write([new Uint8Array([1])]).then(() => 'ok', (e) => e.name);
        const second = await sensor.write([new Uint8Array([2]), new Uint8Array([3])]).then(() => 'ok', (e) => e.name);
        const third = await sensor.write([new Uint8Array([4])]).then(() => 'ok', (e) => e.name);
        return { first, second, third, written }; }""")
    assert out == {"first": "NetworkError", "second": "ok", "third": "ok", "written": [[2], [3], [4]]}
