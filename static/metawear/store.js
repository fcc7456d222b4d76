// The recorder's buffer in the browser (IndexedDB): every notification as it arrived, kept until the server has
// acknowledged the files made from it.
//
// Database "chakamo-recorder", object store "packets" (auto-increment key = arrival order), one record per
// notification: {session, step, segment, stream, run, arrivalMs, bytes}; index "step" on [session, step].
// A step's records are deleted only after its upload was answered with the sha256 of every file matching the
// browser's own (./upload in views/record.js), or when the clinician redoes the step.  A page reload or a
// crash in between loses nothing: the step's files are made again from the records.
// Records are written in batches (one transaction per flush), not one per notification.

const DB = "chakamo-recorder";
const STORE = "packets";

function done(request) {
  return new Promise((resolve, reject) => {
    request.onsuccess = () => resolve(request.result);
    request.onerror = () => reject(request.error);
  });
}

function committed(tx) {
  return new Promise((resolve, reject) => {
    tx.oncomplete = () => resolve();
    tx.onerror = () => reject(tx.error);
    tx.onabort = () => reject(tx.error || new Error("IndexedDB transaction aborted"));
  });
}

export class PacketStore {
  constructor(db) {
    this.db = db;
    this.pending = [];
  }

  static async open(name = DB) {
    const request = indexedDB.open(name, 1);
    request.onupgradeneeded = () => {
      const store = request.result.createObjectStore(STORE, { autoIncrement: true });
      store.createIndex("step", ["session", "step"]);
    };
    return new PacketStore(await done(request));
  }

  /** Queue one notification's record (written by the next flush). */
  add(record) {
    this.pending.push(record);
  }

  /** Write the queued records in one transaction; resolves once they are committed. */
  async flush() {
    if (this.pending.length === 0) return 0;
    const batch = this.pending.splice(0);
    const tx = this.db.transaction(STORE, "readwrite");
    const store = tx.objectStore(STORE);
    for (const r of batch) store.add(r);
    try {
      await committed(tx);
    } catch (err) {
      this.pending.unshift(...batch);        // kept for the next flush: nothing is dropped
      throw err;
    }
    return batch.length;
  }

  /** Every record of one step, in arrival order. */
  async step(session, step) {
    await this.flush();
    const tx = this.db.transaction(STORE, "readonly");
    return done(tx.objectStore(STORE).index("step").getAll(IDBKeyRange.only([session, step])));
  }

  /** Delete one step's records (after the server acknowledged its files, or to redo it). */
  async clear(session, step) {
    await this.flush();
    const tx = this.db.transaction(STORE, "readwrite");
    const keys = await done(tx.objectStore(STORE).index("step").getAllKeys(IDBKeyRange.only([session, step])));
    for (const k of keys) tx.objectStore(STORE).delete(k);
    await committed(tx);
    return keys.length;
  }

  /** The steps of a session that still hold records (not yet acknowledged). */
  async steps(session) {
    await this.flush();
    const tx = this.db.transaction(STORE, "readonly");
    const keys = await done(tx.objectStore(STORE).index("step").getAllKeys(
      IDBKeyRange.bound([session, ""], [session, "\uffff"])));
    const records = await Promise.all(keys.map((k) => done(tx.objectStore(STORE).get(k))));
    return [...new Set(records.map((r) => r.step))];
  }
}
