"""Two MetaMotion sensors for the browser tests: Chromium's DevTools ``BluetoothEmulation`` peripherals that answer
the MetaWear protocol, streaming a simulated session (:mod:`metawear_frames`, the Python twin of the protocol).

What is emulated, and where the boundary is (measured on Debian's chromium 156 with Playwright, spike of
issue 18):

* ``BluetoothEmulation`` is a *browser*-target domain (a page session answers "'BluetoothEmulation.enable'
  wasn't found"); the chooser of ``navigator.bluetooth.requestDevice`` is answered on the page target
  (``DeviceAccess.deviceRequestPrompted`` → ``DeviceAccess.selectPrompt``).  Linux Chromium exposes
  ``navigator.bluetooth`` only with ``--enable-experimental-web-platform-features``.
* Real through the emulation: the chooser, ``gatt.connect()`` (``gattOperationReceived`` connection →
  ``simulateGATTOperationResponse``), service discovery, reads of the Device Information characteristics,
  every command the page writes (``characteristicOperationReceived`` write, with its bytes), subscribing
  (needs the CCCD descriptor 0x2902 on the notify characteristic, else ``startNotifications`` fails with
  NotSupportedError), a refused reconnection, and ``simulateGATTDisconnection`` (the page gets
  ``gattserverdisconnected``; the emulation then forgets the peripheral's services, which the bench registers
  again so that the page's reconnection finds them, as with a real sensor).
* Not possible: the domain has no command that sends a notification (its full command list, from the
  binary's ``/json/protocol``: enable, setSimulatedCentralState, disable, simulatePreconnectedPeripheral,
  simulateAdvertisement, simulateGATTOperationResponse, simulateCharacteristicOperationResponse,
  simulateDescriptorOperationResponse, add/remove Service/Characteristic/Descriptor, simulateGATTDisconnection).
  A ``read`` response does fire ``characteristicvaluechanged``, but only after the page's own ``readValue()``:
  no sensor's stream arrives that way.
* So notifications cross the boundary by a stand-in, installed in the test's page only (:data:`STAND_IN`): it
  keeps the real ``BluetoothRemoteGATTCharacteristic`` of each sensor's notify characteristic once the page
  subscribed, and fires ``characteristicvaluechanged`` on it with the packet as ``value`` and the packet's
  arrival time as the event's ``timeStamp`` (what Chromium stamps a real notification with).  Everything above
  — the page's decoder, time stamps, buffer, uploads — is the product's.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass, field

from metawear_frames import Notification

SERVICE = "326a9000-85cb-9195-d9dd-464cfbbae75a"
COMMAND = "326a9001-85cb-9195-d9dd-464cfbbae75a"
NOTIFY = "326a9006-85cb-9195-d9dd-464cfbbae75a"
CCCD = "00002902-0000-1000-8000-00805f9b34fb"
DEVICE_INFO = "0000180a-0000-1000-8000-00805f9b34fb"
FIRMWARE = "00002a26-0000-1000-8000-00805f9b34fb"
MODEL = "00002a24-0000-1000-8000-00805f9b34fb"
CONNECTION_FAILED = 0x3E    # HCI "Connection Failed to be Established" (Core Spec Vol 1 Part F)

#: the stand-in of notification delivery (module docstring), run before the page's scripts
STAND_IN = """
(() => {
  const subscribed = new Map();           // device name -> the real notify characteristic
  const start = BluetoothRemoteGATTCharacteristic.prototype.startNotifications;
  BluetoothRemoteGATTCharacteristic.prototype.startNotifications = async function () {
    const out = await start.call(this);
    if (this.uuid === '%s') subscribed.set(this.service.device.name, this);
    return out;
  };
  window.__notify = (name, packets) => {   // packets: [[base64 bytes, arrival epoch ms or null], ...]
    const ch = subscribed.get(name);
    if (!ch) return false;
    for (const [b64, arrivalMs] of packets) {
      const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const value = new DataView(bytes.buffer);
      Object.defineProperty(ch, 'value', {configurable: true, get: () => value});
      const ev = new Event('characteristicvaluechanged', {bubbles: true});
      if (arrivalMs !== null) Object.defineProperty(ev, 'timeStamp', {value: arrivalMs - performance.timeOrigin});
      ch.dispatchEvent(ev);
    }
    return true;
  };
})();
""" % NOTIFY


@dataclass
class Peripheral:
    """One emulated MetaMotionR: its GATT ids, the commands it got, its state, its answers waiting."""

    address: str
    name: str
    firmware: str = "1.7.3"
    battery_percent: int = 87
    ids: dict = field(default_factory=dict)
    commands: list[bytes] = field(default_factory=list)
    streaming: set = field(default_factory=set)
    reachable: bool = True
    answers: list[bytes] = field(default_factory=list)
    connections: int = 0

    def command(self, data: bytes) -> None:
        """A command the page wrote: keep it, answer reads, follow the sensors' power."""
        self.commands.append(data)
        module, register = data[0], data[1]
        if register == 0x80 and module in (0x03, 0x13):           # module info: a BMI160 board
            self.answers.append(bytes((module, 0x80, 1 if module == 0x03 else 0, 1)))
        elif (module, register) == (0x11, 0x8C):                   # battery state: charge %, 3.9 V
            self.answers.append(bytes((0x11, 0x8C, self.battery_percent, 0x3C, 0x0F)))
        elif register == 0x01 and module in (0x03, 0x13, 0x15):    # power on / off
            (self.streaming.add if data[2] else self.streaming.discard)(module)

    @property
    def is_streaming(self) -> bool:
        return self.streaming == {0x03, 0x13, 0x15}


class Bench:
    """The emulated central and its peripherals, driven from the test's thread: ``pump()`` answers every
    GATT event that arrived and delivers the sensors' waiting answers; ``notify()`` delivers stream packets."""

    def __init__(self, browser_cdp, page_cdp, page):
        self.cdp, self.page_cdp, self.page = browser_cdp, page_cdp, page
        self.events: list[tuple[str, dict]] = []
        self.log: list[tuple[str, dict]] = []      # every event answered (shown when a wait times out)
        self.peripherals: dict[str, Peripheral] = {}
        self.by_char: dict[str, tuple[Peripheral, str]] = {}
        self.choose: str | None = None
        for name in ("gattOperationReceived", "characteristicOperationReceived", "descriptorOperationReceived"):
            browser_cdp.on(f"BluetoothEmulation.{name}", lambda e, n=name: self.events.append((n, e)))
        page_cdp.on("DeviceAccess.deviceRequestPrompted", lambda e: self.events.append(("prompt", e)))
        browser_cdp.send("BluetoothEmulation.enable", {"state": "powered-on", "leSupported": True})
        page_cdp.send("DeviceAccess.enable")

    def add(self, p: Peripheral) -> Peripheral:
        self.cdp.send("BluetoothEmulation.simulatePreconnectedPeripheral", {
            "address": p.address, "name": p.name, "manufacturerData": [], "knownServiceUuids": [SERVICE]})
        self._gatt_table(p)
        self.peripherals[p.address] = p
        return p

    def _gatt_table(self, p: Peripheral) -> None:
        """Register the sensor's services: MetaWear (command, notify + CCCD) and Device Information."""
        send = self.cdp.send
        service = send("BluetoothEmulation.addService", {"address": p.address, "serviceUuid": SERVICE})["serviceId"]
        p.ids["command"] = send("BluetoothEmulation.addCharacteristic", {
            "serviceId": service, "characteristicUuid": COMMAND,
            "properties": {"write": True, "writeWithoutResponse": True}})["characteristicId"]
        p.ids["notify"] = send("BluetoothEmulation.addCharacteristic", {
            "serviceId": service, "characteristicUuid": NOTIFY, "properties": {"notify": True}})["characteristicId"]
        send("BluetoothEmulation.addDescriptor", {"characteristicId": p.ids["notify"], "descriptorUuid": CCCD})
        dis = send("BluetoothEmulation.addService", {"address": p.address, "serviceUuid": DEVICE_INFO})["serviceId"]
        for key, uuid in (("firmware", FIRMWARE), ("model", MODEL)):
            p.ids[key] = send("BluetoothEmulation.addCharacteristic", {
                "serviceId": dis, "characteristicUuid": uuid, "properties": {"read": True}})["characteristicId"]
        for key, cid in p.ids.items():
            self.by_char[cid] = (p, key)

    def pump(self) -> None:
        """Answer what happened since the last call (in order); deliver the sensors' answers."""
        while self.events:
            kind, e = self.events.pop(0)
            self.log.append((kind, e))
            if kind == "prompt":
                wanted = [d for d in e["devices"] if d["id"] == self.choose]
                if wanted:
                    try:
                        self.page_cdp.send("DeviceAccess.selectPrompt", {"id": e["id"], "deviceId": wanted[0]["id"]})
                        self.choose = None
                    except Exception:   # the prompt was updated (a second event for it): already answered
                        pass
            elif kind == "gattOperationReceived":
                p = self.peripherals[e["address"]]
                ok = p.reachable or e["type"] != "connection"
                if ok and e["type"] == "connection":
                    p.connections += 1
                self.cdp.send("BluetoothEmulation.simulateGATTOperationResponse",
                              {"address": e["address"], "type": e["type"], "code": 0 if ok else CONNECTION_FAILED})
            elif kind == "descriptorOperationReceived":
                self.cdp.send("BluetoothEmulation.simulateDescriptorOperationResponse",
                              {"descriptorId": e["descriptorId"], "type": e["type"], "code": 0})
            else:
                p, key = self.by_char[e["characteristicId"]]
                answer = {"characteristicId": e["characteristicId"], "type": e["type"], "code": 0}
                if e["type"] == "read":
                    text = p.firmware if key == "firmware" else "5"
                    answer["data"] = base64.b64encode(text.encode()).decode()
                elif e["type"] == "write":
                    p.command(base64.b64decode(e["data"]))
                self.cdp.send("BluetoothEmulation.simulateCharacteristicOperationResponse", answer)
        for p in self.peripherals.values():
            if p.answers:
                packets = [[base64.b64encode(a).decode(), None] for a in p.answers]
                if self.page.evaluate("([n, p]) => window.__notify(n, p)", [p.name, packets]):
                    p.answers.clear()

    def notify(self, p: Peripheral, packets: list[Notification], latency_ms: float = 4.0) -> None:
        """Deliver stream packets of one sensor, each arriving ``latency_ms`` after its last sample was taken."""
        data = [[base64.b64encode(n.payload).decode(), n.arrival_s * 1e3 + latency_ms] for n in packets]
        assert self.page.evaluate("([n, p]) => window.__notify(n, p)", [p.name, data]), f"{p.name} not subscribed"

    def disconnect(self, p: Peripheral) -> None:
        """The sensor goes out of reach: the link drops and connection attempts fail until it is back."""
        p.reachable = False
        p.streaming.clear()
        self.cdp.send("BluetoothEmulation.simulateGATTDisconnection", {"address": p.address})
        # the emulation forgets a peripheral's services when it disconnects (measured: getPrimaryService then
        # answers NotFoundError); a real sensor keeps its GATT table, so the bench registers it again
        self._gatt_table(p)

    def wait(self, until, what: str, timeout_s: float = 120.0) -> None:
        """Pump until ``until()`` holds (the page works meanwhile).  A test waits through this, not Playwright's
        ``expect``, whenever the page may be waiting for a sensor: nothing answers the sensors between pumps."""
        import time

        end = time.monotonic() + timeout_s
        while not until():
            if time.monotonic() > end:
                raise AssertionError(f"timed out waiting for {what}; last events: {self.log[-12:]}")
            self.pump()
            self.page.wait_for_timeout(30)
        self.pump()
