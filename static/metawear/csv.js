// Recorded streams as MetaBase CSV files: the documented format the ingestion reads (app/pipeline/ingestion/
// metabase.py), written character for character as the project's own writer (write_metabase_csv) writes it at
// the start's UTC offset (tests/static/test_metawear_recording.py compares the two).  That is not necessarily
// what MetaBase itself would write for the same samples: see "Local time" below.
//
// Name   {label}_MetaWear_{YYYY-MM-DDTHH.MM.SS.mmm}_{MAC}_{Accelerometer|Gyroscope|Magnetometer}_{rate:.3f}Hz_{firmware}.csv
//        (time of the first sample in the browser's local time, as MetaBase names a file with the phone's
//        local time: the server reads the name's date as the recording's local day, the report's
//        "recordings' date", app/pipeline/results.py recorded_dates)
// Header epoch (ms),time (+01:00),elapsed (s),x-axis (g),y-axis (g),z-axis (g)
// Rows   integer epoch ms (UTC), its local time, seconds since the first row with 3 decimals, the values with
//        3 decimals (g, deg/s) or 9 (T: the magnetometer's µT / 1e6, as MetaBase exports tesla).
// Local time: the browser's UTC offset at the recording's first sample, for the name, the header's zone label
// and every row; a recording across a daylight-saving change keeps its start's offset to its end.  Real
// MetaBase exports differ in two ways this file does not copy: their header's zone label carries no meaning
// (the exports in the project's data say "time (-13:00)" above rows written at UTC−4), and MetaBase formats
// each row with the phone's local time of that moment, so its rows' offset would change at a daylight-saving
// change (none of those exports spans one).  The server reads neither the label nor the time column: the
// epoch column (UTC) is the time base, the name's date the local day.
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

/** The browser's UTC offset at epoch ms, minutes (east positive: +60 in Madrid in winter). */
export function utcOffsetMin(epochMs) {
  return -new Date(epochMs).getTimezoneOffset();
}

/** The time of epoch ms at `offsetMin` from UTC as numpy's datetime_as_string(unit="ms"): 2026-11-22T10:00:00.123. */
export function isoMs(epochMs, offsetMin = 0) {
  return new Date(epochMs + offsetMin * 60000).toISOString().slice(0, -1);
}

/** The header's zone label of an offset: "+01:00", "-03:30" (the Python writer's _tz_label, "epoch" dialect). */
export function zoneLabel(offsetMin) {
  const a = Math.abs(offsetMin);
  const two = (n) => String(n).padStart(2, "0");
  return `${offsetMin < 0 ? "-" : "+"}${two(Math.floor(a / 60))}:${two(a % 60)}`;
}

/** The file name of one stream (label without "_"; mac as 12 hex digits, any separators); its date-time is the
 * first sample's in local time at `offsetMin` (default: the browser's). */
export function fileName(label, startEpochMs, mac, kind, rateHz, firmware, offsetMin = utcOffsetMin(startEpochMs)) {
  const stamp = isoMs(startEpochMs, offsetMin).replace(/:/g, ".");
  const hex = mac.replace(/[:-]/g, "").toUpperCase();
  return `${label}_MetaWear_${stamp}_${hex}_${STREAM_WORD[kind]}_${rateHz.toFixed(3)}Hz_${firmware}.csv`;
}

/** The CSV text of one stream: epochMs (integers, increasing) and values [[x, y, z], …] in the board's units
 * (g, °/s, µT); the time column local at `offsetMin` (default: the browser's at the first sample). */
export function csvText(kind, epochMs, values, offsetMin = utcOffsetMin(epochMs[0])) {
  const unit = FILE_UNIT[kind];
  const digits = DECIMALS[kind];
  const lines = [`epoch (ms),time (${zoneLabel(offsetMin)}),elapsed (s),x-axis (${unit}),y-axis (${unit}),z-axis (${unit})`];
  const t0 = epochMs[0];
  for (let k = 0; k < epochMs.length; k++) {
    const v = kind === "mag" ? values[k].map((ut) => ut / 1e6) : values[k];
    const cells = v.map((x) => pyFixed(x, digits)).join(",");
    lines.push(`${epochMs[k]},${isoMs(epochMs[k], offsetMin)},${pyFixed((epochMs[k] - t0) / 1e3, 3)},${cells}`);
  }
  return lines.join("\n") + "\n";
}
