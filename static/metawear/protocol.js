// The MetaWear BLE protocol (MbientLab MetaMotionR / RL / S): commands to write and notifications to read.
//
// Written from MbientLab's public description of the protocol and Bosch's sensor datasheets, not from any SDK.
//
// Transport (GATT)
//   service   326a9000-85cb-9195-d9dd-464cfbbae75a  the MetaWear service
//   command   326a9001-…  written (without response) with one command per write
//   notify    326a9006-…  every answer and every streamed sample arrives here as a notification
//   0x180a    Device Information: firmware revision 0x2a26, model number 0x2a24, serial number 0x2a25
// Every packet, both ways, is [module id, register id, payload…]; a read sets bit 7 of the register id and
// its answer comes back with that bit set.  Multi-byte numbers are little-endian, samples int16.
//
// Modules and registers used here
//   accelerometer 0x03: 0x01 power (1 on, 0 off), 0x02 data interrupt enable ([1, 0] on, [0, 1] off),
//     0x03 config [ACC_CONF, ACC_RANGE] (the chip's own two registers); module info read [0x03, 0x80] →
//     [0x03, 0x80, implementation, revision] with implementation 1 = BMI160, 4 = BMI270
//   gyroscope 0x13: 0x01 power, 0x02 interrupt enable, 0x03 config [GYR_CONF, GYR_RANGE];
//     implementation 0 = BMI160, 1 = BMI270
//   The data registers depend on the chip (MbientLab's register maps of each board, DATA_REGISTERS below):
//                       single   packed (three samples)
//     BMI160 acc        0x04     0x1c        (MetaMotion R / RL)
//     BMI160 gyro       0x05     0x07
//     BMI270 acc        0x04     0x05        (MetaMotion S)
//     BMI270 gyro       0x04     0x05
//   so one (module, register) means different streams on the two boards (0x13 0x05 is a BMI160's single
//   gyroscope sample and a BMI270's packed one): a board's packets are decoded with its own table.  Packed
//   data exists from module revision 1 on (the revision byte of the module info answer); an older module
//   streams single samples.
//   magnetometer 0x15 (BMM150): 0x01 power, 0x02 interrupt enable, 0x03 data rate, 0x04 repetitions
//     [(xy − 1)/2, z − 1], 0x05 data, 0x09 packed
//   settings 0x11: 0x0c battery state, read → [charge %, voltage mV as uint16]
//   LED 0x02 (the board's RGB LED; MbientLab's LED module description): 0x01 play ([1] play, [2] autoplay,
//     [0] pause), 0x02 stop ([1] stop and clear the patterns, [0] stop), 0x03 pattern of one colour:
//     [colour (0 green, 1 red, 2 blue), 0x02, high intensity, low intensity (0–31), rise ms, high ms, fall ms,
//      pulse duration ms, delay ms (uint16 LE each; the delay from module revision 1), repeat count (0xff: forever)]
//   Subscribing to a data register ([module, register, 1]) makes the board notify it; [module, register, 0] stops.
//
// Configuration (ODR and range codes from the Bosch datasheets; the board forwards the two config bytes)
//   ACC_CONF = odr | bwp << 4 (| filter_perf << 7 on the BMI270), odr 100 Hz = 8, bwp 2 = normal filter
//   ACC_RANGE BMI160: ±2/4/8/16 g = 0x03/0x05/0x08/0x0c; BMI270: 0/1/2/3
//   GYR_CONF = odr | bwp << 4, odr 100 Hz = 8; GYR_RANGE ±2000/1000/500/250/125 °/s = 0/1/2/3/4 (both chips)
//   BMM150 data rate 2/6/8/10/15/20/25/30 Hz = 1/2/3/0/4/5/6/7; repetitions xy 9, z 15 ("regular" preset,
//   fast enough for 20 Hz)
// Scaling (the datasheets' sensitivities at each range)
//   acc  LSB per g       = 32768 / range_g          (16384 at ±2 g … 2048 at ±16 g)
//   gyr  LSB per °/s     = 16.4 at ±2000, 32.8, 65.6, 131.2, 262.4 at ±125 (the datasheet's, not 32768 / range)
//   mag  LSB per µT      = 16
//
// The protocol's sensors stream with no time stamp and no counter: time is given on arrival by the caller
// (./timeline.js), and a sample lost in the air is found there from the arrival times.

export const SERVICE = "326a9000-85cb-9195-d9dd-464cfbbae75a";
export const COMMAND_CHAR = "326a9001-85cb-9195-d9dd-464cfbbae75a";
export const NOTIFY_CHAR = "326a9006-85cb-9195-d9dd-464cfbbae75a";
export const DEVICE_INFO_SERVICE = 0x180a;
export const FIRMWARE_CHAR = 0x2a26;
export const MODEL_CHAR = 0x2a24;
export const SERIAL_CHAR = 0x2a25;

export const MODULE = Object.freeze({ LED: 0x02, ACCELEROMETER: 0x03, SETTINGS: 0x11, GYRO: 0x13, MAGNETOMETER: 0x15 });
const READ = 0x80;
const REG = Object.freeze({ POWER: 0x01, INTERRUPT: 0x02, CONFIG: 0x03, MODULE_INFO: 0x00, BATTERY: 0x0c,
  MAG_RATE: 0x03, MAG_REPETITIONS: 0x04 });
/** Data registers of each stream per chip: [single sample, three packed samples] (table in the header). */
const DATA_REGISTERS = Object.freeze({
  acc: Object.freeze({ BMI160: [0x04, 0x1c], BMI270: [0x04, 0x05] }),
  gyr: Object.freeze({ BMI160: [0x05, 0x07], BMI270: [0x04, 0x05] }),
  mag: Object.freeze({ BMM150: [0x05, 0x09] }),
});
/** The module revision from which a module streams packed samples. */
const PACKED_REVISION = 1;
const STREAM_MODULE = Object.freeze({ acc: MODULE.ACCELEROMETER, gyr: MODULE.GYRO, mag: MODULE.MAGNETOMETER });

export const ACC_CHIP = Object.freeze({ 1: "BMI160", 4: "BMI270" });
/** A MetaMotion R's chips (both modules able to pack): the default of the functions below. */
export const BMI160_BOARD = Object.freeze({ acc: "BMI160", gyr: "BMI160", packed: Object.freeze({ acc: true, gyr: true }) });
export const GYRO_CHIP = Object.freeze({ 0: "BMI160", 1: "BMI270" });
const GYRO_CHIP_NAMES = Object.freeze({ BMI160: 0, BMI270: 1 });

const BOSCH_ODR = Object.freeze({ 25: 6, 50: 7, 100: 8, 200: 9, 400: 10, 800: 11, 1600: 12 });
const ACC_RANGE_CODE = Object.freeze({
  BMI160: { 2: 0x03, 4: 0x05, 8: 0x08, 16: 0x0c },
  BMI270: { 2: 0x00, 4: 0x01, 8: 0x02, 16: 0x03 },
});
const GYR_RANGE_CODE = Object.freeze({ 2000: 0, 1000: 1, 500: 2, 250: 3, 125: 4 });
/** Sensitivity of the gyroscope at each range, LSB per °/s (Bosch BMI160/BMI270 datasheets). */
const GYR_LSB_PER_DPS = Object.freeze({ 2000: 16.4, 1000: 32.8, 500: 65.6, 250: 131.2, 125: 262.4 });
const MAG_RATE_CODE = Object.freeze({ 2: 1, 6: 2, 8: 3, 10: 0, 15: 4, 20: 5, 25: 6, 30: 7 });
export const MAG_LSB_PER_UT = 16;
const MAG_REPETITIONS = Object.freeze({ xy: 9, z: 15 });

/** The protocol's recording set-up (shared/DESIGN.md §1: acc and gyro 100 Hz, magnetometer 20 Hz): rates in Hz,
 * ranges ±16 g and ±2000 °/s (those of the MetaMotion sensor model in estimators/simulation/spec.py). */
export const PROTOCOL_CONFIG = Object.freeze({ accHz: 100, gyrHz: 100, magHz: 20, accRangeG: 16, gyrRangeDps: 2000 });

export class ProtocolError extends Error {
  constructor(message, code = "protocol") {
    super(message);
    this.code = code;
  }
}

function pick(table, key, what) {
  if (!(key in table)) throw new ProtocolError(`${what} ${key} is not one the sensor offers (${Object.keys(table).join(", ")})`);
  return table[key];
}

/** LSB → unit factors of a configuration: {acc: LSB per g, gyr: LSB per °/s, mag: LSB per µT}. */
export function sensitivities(config = PROTOCOL_CONFIG) {
  pick(GYR_LSB_PER_DPS, config.gyrRangeDps, "gyroscope range");
  if (![2, 4, 8, 16].includes(config.accRangeG)) pick({}, config.accRangeG, "accelerometer range");
  return { acc: 32768 / config.accRangeG, gyr: GYR_LSB_PER_DPS[config.gyrRangeDps], mag: MAG_LSB_PER_UT };
}

// ------------------------------------------------------------------------------------------ encoder
/** Command that reads a module's info register (its answer names the chip: ACC_CHIP, GYRO_CHIP). */
export function readModuleInfo(module) {
  return Uint8Array.of(module, READ | REG.MODULE_INFO);
}

/** Command that reads the battery state (answer decoded as {kind: "battery", chargePercent, voltageMv}). */
export function readBattery() {
  return Uint8Array.of(MODULE.SETTINGS, READ | REG.BATTERY);
}

const LED_REG = Object.freeze({ PLAY: 0x01, STOP: 0x02, PATTERN: 0x03 });
export const LED_COLOUR = Object.freeze({ green: 0, red: 1, blue: 2 });
/** The blink that shows which physical sensor is which: full brightness 200 ms of every 500 ms, six times (3 s). */
export const BLINK = Object.freeze({ high: 31, low: 0, riseMs: 0, highMs: 200, fallMs: 0, pulseMs: 500, delayMs: 0, repeat: 6 });

/** Commands that blink the board's LED in `colour` ("green", "red", "blue") with `pattern` (BLINK's fields): clear
 * what it had, write the pattern, play it. */
export function blinkLed(colour = "green", pattern = BLINK) {
  const c = pick(LED_COLOUR, colour, "LED colour");
  const p = pattern;
  for (const [name, max] of [["high", 31], ["low", 31], ["repeat", 255]]) {
    if (!Number.isInteger(p[name]) || p[name] < 0 || p[name] > max) throw new ProtocolError(`LED ${name} ${p[name]} is not 0–${max}`);
  }
  const config = new Uint8Array(17);
  const view = new DataView(config.buffer);
  config.set([MODULE.LED, LED_REG.PATTERN, c, 0x02, p.high, p.low]);
  [p.riseMs, p.highMs, p.fallMs, p.pulseMs, p.delayMs].forEach((ms, i) => {
    if (!Number.isInteger(ms) || ms < 0 || ms > 0xffff) throw new ProtocolError(`LED time ${ms} ms is not 0–65535`);
    view.setUint16(6 + 2 * i, ms, true);
  });
  config[16] = p.repeat;
  return [stopLed(), config, Uint8Array.of(MODULE.LED, LED_REG.PLAY, 0x01)];
}

/** Command that stops the LED and clears its patterns. */
export function stopLed() {
  return Uint8Array.of(MODULE.LED, LED_REG.STOP, 0x01);
}

/** Commands that set rates and ranges of the three sensors (nothing streams yet).
 * chips: {acc: "BMI160"|"BMI270", gyr: "BMI160"|"BMI270"} from the module info answers. */
export function configure(config = PROTOCOL_CONFIG, chips = BMI160_BOARD) {
  const accRanges = pick(ACC_RANGE_CODE, chips.acc, "accelerometer chip");
  pick(GYRO_CHIP_NAMES, chips.gyr, "gyroscope chip");
  const accOdr = pick(BOSCH_ODR, config.accHz, "accelerometer rate (Hz)");
  const gyrOdr = pick(BOSCH_ODR, config.gyrHz, "gyroscope rate (Hz)");
  const accConf = accOdr | (2 << 4) | (chips.acc === "BMI270" ? 0x80 : 0);
  return [
    Uint8Array.of(MODULE.ACCELEROMETER, REG.CONFIG, accConf, pick(accRanges, config.accRangeG, "accelerometer range (g)")),
    Uint8Array.of(MODULE.GYRO, REG.CONFIG, gyrOdr | (2 << 4), pick(GYR_RANGE_CODE, config.gyrRangeDps, "gyroscope range (°/s)")),
    Uint8Array.of(MODULE.MAGNETOMETER, REG.POWER, 0x00),   // the BMM150 takes its settings while stopped
    Uint8Array.of(MODULE.MAGNETOMETER, REG.MAG_REPETITIONS, (MAG_REPETITIONS.xy - 1) / 2, MAG_REPETITIONS.z - 1),
    Uint8Array.of(MODULE.MAGNETOMETER, REG.MAG_RATE, pick(MAG_RATE_CODE, config.magHz, "magnetometer rate (Hz)")),
  ];
}
/** The data registers of a board's three streams: {acc, gyr, mag} each [single, packed] register. */
export function dataRegisters(chips = BMI160_BOARD) {
  return { acc: pick(DATA_REGISTERS.acc, chips.acc, "accelerometer chip"),
    gyr: pick(DATA_REGISTERS.gyr, chips.gyr, "gyroscope chip"), mag: DATA_REGISTERS.mag.BMM150 };
}

/** Commands that subscribe to the three data registers and switch the sensors on (after configure()).
 * chips: chipsOf()'s answer; acc and gyro send three samples per notification (fewer packets at 100 Hz)
 * where the module can (chips.packed), one otherwise. */
export function startStreaming(chips = BMI160_BOARD) {
  const regs = dataRegisters(chips);
  const out = [];
  for (const kind of ["acc", "gyr", "mag"]) {
    const module = STREAM_MODULE[kind];
    const reg = regs[kind][kind !== "mag" && chips.packed?.[kind] ? 1 : 0];
    out.push(Uint8Array.of(module, reg, 0x01), Uint8Array.of(module, REG.INTERRUPT, 0x01, 0x00),
      Uint8Array.of(module, REG.POWER, 0x01));
  }
  return out;
}

/** Commands that stop the three sensors and their notifications (both data registers of each). */
export function stopStreaming(chips = BMI160_BOARD) {
  const regs = dataRegisters(chips);
  const out = [];
  for (const kind of ["acc", "gyr", "mag"]) {
    const module = STREAM_MODULE[kind];
    out.push(Uint8Array.of(module, REG.POWER, 0x00), Uint8Array.of(module, REG.INTERRUPT, 0x00, 0x01));
    for (const reg of regs[kind]) out.push(Uint8Array.of(module, reg, 0x00));
  }
  return out;
}

// ------------------------------------------------------------------------------------------ decoder
const DATA_KINDS = new Map();    // "acc chip/gyro chip" → Map((module << 8) | register → {kind, samples})

function dataKinds(chips) {
  const key = `${chips.acc}/${chips.gyr}`;
  if (!DATA_KINDS.has(key)) {
    const table = new Map();
    for (const [kind, regs] of Object.entries(dataRegisters(chips))) {
      regs.forEach((reg, packed) => table.set((STREAM_MODULE[kind] << 8) | reg, { kind, samples: packed ? 3 : 1 }));
    }
    DATA_KINDS.set(key, table);
  }
  return DATA_KINDS.get(key);
}

/** One notification → what it says.
 *   samples: {kind: "acc"|"gyr"|"mag", values: [[x, y, z], …]} in g, °/s, µT (one or three samples, in order)
 *   {kind: "module", module, implementation, revision}   {kind: "battery", chargePercent, voltageMv}
 *   {kind: "other", module, register}   anything else the board says (ignored by callers)
 * bytes: DataView, ArrayBuffer or Uint8Array; chips: the board's (chipsOf), whose table names its data
 * registers.  A data packet of the wrong length is a ProtocolError. */
export function decode(bytes, scale = sensitivities(), chips = BMI160_BOARD) {
  const view = bytes instanceof DataView ? bytes
    : new DataView(bytes.buffer ?? bytes, bytes.byteOffset ?? 0, bytes.byteLength);
  if (view.byteLength < 2) throw new ProtocolError(`notification of ${view.byteLength} byte(s): too short`);
  const module = view.getUint8(0);
  const register = view.getUint8(1);
  const data = dataKinds(chips).get((module << 8) | register);
  if (data) {
    const expected = 2 + 6 * data.samples;
    if (view.byteLength !== expected) {
      throw new ProtocolError(`${data.kind} packet of ${view.byteLength} bytes, expected ${expected}`);
    }
    const lsb = scale[data.kind];
    const values = [];
    for (let s = 0; s < data.samples; s++) {
      const at = 2 + 6 * s;
      values.push([0, 2, 4].map((k) => view.getInt16(at + k, true) / lsb));
    }
    return { kind: data.kind, values };
  }
  if (register === (READ | REG.MODULE_INFO) && view.byteLength >= 4) {
    return { kind: "module", module, implementation: view.getUint8(2), revision: view.getUint8(3) };
  }
  if (module === MODULE.SETTINGS && register === (READ | REG.BATTERY) && view.byteLength >= 5) {
    return { kind: "battery", chargePercent: view.getUint8(2), voltageMv: view.getUint16(3, true) };
  }
  return { kind: "other", module, register };
}

/** The chips of a board from its module info answers: {acc, gyr} names and packed: {acc, gyr} (the module's
 * revision ≥ PACKED_REVISION), or a ProtocolError for one this recorder does not know (another MetaWear model
 * without BMI160/BMI270). */
export function chipsOf(accInfo, gyrInfo) {
  const acc = ACC_CHIP[accInfo.implementation];
  const gyr = GYRO_CHIP[gyrInfo.implementation];
  if (!acc) throw new ProtocolError(`accelerometer implementation ${accInfo.implementation} is not a BMI160 or BMI270`, "unsupported_sensor");
  if (!gyr) throw new ProtocolError(`gyroscope implementation ${gyrInfo.implementation} is not a BMI160 or BMI270`, "unsupported_sensor");
  return { acc, gyr, packed: { acc: accInfo.revision >= PACKED_REVISION, gyr: gyrInfo.revision >= PACKED_REVISION } };
}
