// Recorded streams as MetaBase CSV files: the documented format the ingestion reads (app/pipeline/ingestion/
// metabase.py), written character for character as its writer does, so a recording made in the browser is
// the same file a MetaBase export of the same samples gives.
//
// Name   {label}_MetaWear_{YYYY-MM-DDTHH.MM.SS.mmm}_{MAC}_{Accelerometer|Gyroscope|Magnetometer}_{rate:.3f}Hz_{firmware}.csv
//        (time of the first sample in UTC)
// Header epoch (ms),time (+00:00),elapsed (s),x-axis (g),y-axis (g),z-axis (g)
// Rows   integer epoch ms, its UTC time, seconds since the first row with 3 decimals, the values with
//        3 decimals (g, deg/s) or 9 (T: the magnetometer's µT / 1e6, as MetaBase exports tesla).
// Numbers are formatted as Python's f"{x:.nf}" does: the exact binary value rounded, a tie (x · 2^(n+1) an odd
// integer, the only way a binary number ends in a 5 right after the n-th decimal) to the even digit.

const STREAM_WORD = Object.freeze({ acc: "Accelerometer", gyr: "Gyroscope", mag: "Magnetometer" });
const FILE_UNIT = Object.freeze({ acc: "g", gyr: "deg/s", mag: "T" });
const DECIMALS = Object.freeze({ acc: 3, gyr: 3, mag: 9 });

/** x with `digits` decimals exactly as Python's format(x, f".{digits}f") writes it (finite x). */
export function pyFixed(x, digits) {
  const text = x.toFixed(digits);          // rounds the exact value; a tie goes away from zero
  const scaled = Math.abs(x) * 2 ** (digits + 1);
  if (!(Number.isInteger(scaled) && scaled % 2 === 1)) return Object.is(x, -0) ? `-${text}` : text;
  const last = Number(text[text.length - 1]);
  if (last % 2 === 0) return text;          // away from zero already landed on the even digit
  // one unit of the last decimal back towards zero: the even neighbour Python picks
  const unit = 10 ** -digits;
  const back = (Math.abs(Number(text)) - unit).toFixed(digits);
  return x < 0 ? `-${back}` : back;
}

/** The UTC time of epoch ms as numpy's datetime_as_string(unit="ms"): 2026-11-22T10:00:00.123. */
export function isoMs(epochMs) {
  return new Date(epochMs).toISOString().slice(0, -1);
}

/** The file name of one stream (label without "_"; mac as 12 hex digits, any separators). */
export function fileName(label, startEpochMs, mac, kind, rateHz, firmware) {
  const stamp = isoMs(startEpochMs).replace(/:/g, ".");
  const hex = mac.replace(/[:-]/g, "").toUpperCase();
  return `${label}_MetaWear_${stamp}_${hex}_${STREAM_WORD[kind]}_${rateHz.toFixed(3)}Hz_${firmware}.csv`;
}

/** The CSV text of one stream: epochMs (integers, increasing) and values [[x, y, z], …] in the board's units
 * (g, °/s, µT). */
export function csvText(kind, epochMs, values) {
  const unit = FILE_UNIT[kind];
  const digits = DECIMALS[kind];
  const lines = [`epoch (ms),time (+00:00),elapsed (s),x-axis (${unit}),y-axis (${unit}),z-axis (${unit})`];
  const t0 = epochMs[0];
  for (let k = 0; k < epochMs.length; k++) {
    const v = kind === "mag" ? values[k].map((ut) => ut / 1e6) : values[k];
    const cells = v.map((x) => pyFixed(x, digits)).join(",");
    lines.push(`${epochMs[k]},${isoMs(epochMs[k])},${pyFixed((epochMs[k] - t0) / 1e3, 3)},${cells}`);
  }
  return lines.join("\n") + "\n";
}
