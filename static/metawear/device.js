// One MetaMotion sensor over Web Bluetooth: pick, connect, identify (firmware, chips, battery), configure,
// stream, and reconnect after a drop.  The bytes are ./protocol.js's; this module only moves them.
//
// Web Bluetooth (Chromium; on Linux behind chrome://flags "Experimental Web Platform features") gives a
// BluetoothDevice from the browser's chooser; its GATT server holds the MetaWear service, whose command
// characteristic takes one command per write (with response, so commands keep their order) and whose notify
// characteristic brings every answer and sample.  The time a notification arrived is its event's timeStamp
// on the page's clock (performance.timeOrigin + timeStamp = epoch ms): ./timeline.js turns those into stamps.
//
// A drop (gattserverdisconnected) ends the sensor's run (onDropped) and, while the sensor is wanted, starts
// reconnection attempts every RECONNECT_MS; every connection first stops whatever the board still streams;
// once connected again, a sensor still meant to stream is configured and started again (onReconnect) (the samples of the gap are gone: the sensor streams, it
// does not log).  The browser hides the sensor's MAC: `serial` is a stand-in of the same shape, the first six
// bytes of SHA-256(device.id) with the locally-administered bit set (stable for this sensor in this browser
// profile; never a real MAC).

import * as protocol from "./protocol.js";

const ANSWER_MS = 3000;
const RECONNECT_MS = 1000;
const RECONNECT_TRIES = 60;

export class SensorError extends Error {
  constructor(code, detail = "") {
    super(`${code}${detail ? `: ${detail}` : ""}`);
    this.code = code;
  }
}

/** Web Bluetooth's errors (DOMException names, Web Bluetooth spec §4 and §6) → the recorder's codes, whose
 * sentences the page has in es/en/pt (record.error.<code>); null for an error that is not one of them. */
export const BLUETOOTH_ERRORS = Object.freeze({
  NetworkError: "bt_network", SecurityError: "bt_security", NotSupportedError: "bt_not_supported",
  InvalidStateError: "bt_invalid_state", NotAllowedError: "bt_not_allowed", AbortError: "bt_abort",
  TimeoutError: "bt_timeout",
});

export function bluetoothErrorCode(err) {
  return err && typeof err.name === "string" ? BLUETOOTH_ERRORS[err.name] ?? null : null;
}

/** The browser's chooser for a MetaWear sensor (must run in a click handler). */
export async function pickSensor(bluetooth = navigator.bluetooth) {
  if (!bluetooth) throw new SensorError("no_bluetooth");
  return bluetooth.requestDevice({ filters: [{ services: [protocol.SERVICE] }],
    optionalServices: [protocol.DEVICE_INFO_SERVICE] });
}

async function stableSerial(id) {
  const digest = new Uint8Array(await crypto.subtle.digest("SHA-256", new TextEncoder().encode(id)));
  digest[0] = (digest[0] | 0x02) & 0xfe;                    // locally administered, unicast
  return Array.from(digest.slice(0, 6), (b) => b.toString(16).padStart(2, "0")).join("").toUpperCase();
}

export class MetaWearSensor {
  /** device: a BluetoothDevice; handlers: onSamples(kind, values, arrivalMs, raw), onState(state),
   * onDropped() (the link dropped while streaming), onReconnect(), onBadPacket(error) (a notification the board's table cannot decode) — all optional. */
  constructor(device, handlers = {}) {
    this.device = device;
    this.handlers = handlers;
    this.state = "idle";              // idle | connecting | connected | streaming | reconnecting | lost
    this.info = { name: device.name || "MetaWear", firmware: "", model: "", chips: null, battery: null, serial: "" };
    this.config = protocol.PROTOCOL_CONFIG;
    this.scale = protocol.sensitivities(this.config);
    this.waiting = [];
    this.streaming = false;
    this.wanted = false;
    this.reconnecting = false;
    this.queue = Promise.resolve();
    this.onNotify = (ev) => this.notified(ev);
    device.addEventListener("gattserverdisconnected", () => this.dropped());
  }

  setState(state) {
    this.state = state;
    this.handlers.onState?.(state);
  }

  /** Connect, subscribe, and read what the sensor is: firmware, chips, battery. */
  async connect() {
    this.wanted = true;
    this.setState("connecting");
    const server = await this.device.gatt.connect();
    const service = await server.getPrimaryService(protocol.SERVICE);
    this.command = await service.getCharacteristic(protocol.COMMAND_CHAR);
    this.notify = await service.getCharacteristic(protocol.NOTIFY_CHAR);
    this.notify.removeEventListener("characteristicvaluechanged", this.onNotify);
    this.notify.addEventListener("characteristicvaluechanged", this.onNotify);
    await this.notify.startNotifications();
    // a board may still stream from before (a page reloaded, a link dropped mid-step): quiet it first, so that
    // no sample arrives before this connection asks for it
    await this.write(protocol.stopStreaming(this.info.chips ?? protocol.BMI160_BOARD));
    if (!this.info.serial) this.info.serial = await stableSerial(this.device.id);
    if (!this.info.firmware) await this.readDeviceInfo(server);
    const acc = await this.ask(protocol.readModuleInfo(protocol.MODULE.ACCELEROMETER),
      (a) => a.kind === "module" && a.module === protocol.MODULE.ACCELEROMETER);
    const gyr = await this.ask(protocol.readModuleInfo(protocol.MODULE.GYRO),
      (a) => a.kind === "module" && a.module === protocol.MODULE.GYRO);
    this.info.chips = protocol.chipsOf(acc, gyr);
    await this.readBattery();
    this.setState("connected");
  }

  async readDeviceInfo(server) {
    try {
      const dis = await server.getPrimaryService(protocol.DEVICE_INFO_SERVICE);
      const text = async (uuid) => new TextDecoder().decode(await (await dis.getCharacteristic(uuid)).readValue());
      this.info.firmware = (await text(protocol.FIRMWARE_CHAR)).replace(/[^0-9A-Za-z.-]/g, "");
      this.info.model = await text(protocol.MODEL_CHAR);
    } catch (_) {
      this.info.firmware = "unknown";   // the recording goes on; the file name says it was not read
    }
  }

  async readBattery() {
    const answer = await this.ask(protocol.readBattery(), (a) => a.kind === "battery");
    this.info.battery = { chargePercent: answer.chargePercent, voltageMv: answer.voltageMv };
    return this.info.battery;
  }

  /** Write commands in order (one write each), after every earlier write has settled.  A failed write fails
   * its own caller only: the queue goes on past it (a refused blink must not block the next configure and
   * start, or a reconnection's stop). */
  write(commands) {
    const run = this.queue.catch(() => {}).then(async () => {
      for (const c of commands) await this.command.writeValueWithResponse(c);
    });
    this.queue = run;
    return run;
  }

  /** Write `command` and wait for the first notification `match(decoded)` accepts. */
  ask(command, match) {
    return new Promise((resolve, reject) => {
      const entry = { match, resolve, reject };
      const timer = setTimeout(() => {
        this.waiting = this.waiting.filter((w) => w !== entry);
        reject(new SensorError("no_answer", Array.from(command).join(",")));
      }, ANSWER_MS);
      entry.resolve = (a) => { clearTimeout(timer); resolve(a); };
      this.waiting.push(entry);
      this.write([command]).catch(reject);
    });
  }

  notified(ev) {
    const view = ev.target.value;
    const arrivalMs = performance.timeOrigin + ev.timeStamp;
    let answer;
    try {
      answer = protocol.decode(view, this.scale, this.info.chips ?? protocol.BMI160_BOARD);
    } catch (err) {
      this.handlers.onBadPacket?.(err);
      return;
    }
    if (answer.kind === "acc" || answer.kind === "gyr" || answer.kind === "mag") {
      const raw = new Uint8Array(view.buffer.slice(view.byteOffset, view.byteOffset + view.byteLength));
      this.handlers.onSamples?.(answer.kind, answer.values, arrivalMs, raw);
      return;
    }
    const i = this.waiting.findIndex((w) => w.match(answer));
    if (i >= 0) this.waiting.splice(i, 1)[0].resolve(answer);
  }

  /** Blink the sensor's LED (protocol.blinkLed): shows the clinician which physical sensor this one is. */
  async blink(colour = "green") {
    if (!this.device.gatt.connected) throw new SensorError("disconnected");
    await this.write(protocol.blinkLed(colour));
  }

  /** Configure the protocol's rates and ranges and start the three streams. */
  async start() {
    await this.write([...protocol.configure(this.config, this.info.chips), ...protocol.startStreaming(this.info.chips)]);
    this.streaming = true;
    this.setState("streaming");
  }

  async stop() {
    this.streaming = false;
    if (this.device.gatt.connected) await this.write(protocol.stopStreaming(this.info.chips ?? protocol.BMI160_BOARD));
    this.setState(this.device.gatt.connected ? "connected" : this.state);
  }

  /** Let go of the sensor (no reconnection). */
  disconnect() {
    this.wanted = false;
    this.streaming = false;
    if (this.device.gatt.connected) this.device.gatt.disconnect();
    this.setState("idle");
  }

  async dropped() {
    for (const w of this.waiting.splice(0)) w.reject(new SensorError("disconnected"));
    // the run ends with the link: whatever arrives from now on belongs to a new run (./timeline.js)
    if (this.streaming) this.handlers.onDropped?.();
    if (!this.wanted || this.reconnecting) return;
    this.reconnecting = true;
    const wasStreaming = this.streaming;
    this.setState("reconnecting");
    try {
      for (let attempt = 0; attempt < RECONNECT_TRIES && this.wanted; attempt++) {
        await new Promise((r) => setTimeout(r, RECONNECT_MS));
        try {
          await this.connect();
          // streaming still wanted (the step may have been stopped while the sensor was away)
          if (wasStreaming && this.streaming) {
            this.handlers.onReconnect?.();
            await this.start();
          }
          return;
        } catch (_) {
          // out of reach still, or connected without its services yet: start the next attempt from scratch
          if (this.device.gatt.connected) this.device.gatt.disconnect();
        }
      }
      if (this.wanted) this.setState("lost");
    } finally {
      this.reconnecting = false;
    }
  }
}
