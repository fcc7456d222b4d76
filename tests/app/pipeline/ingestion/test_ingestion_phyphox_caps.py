"""The size caps hold through ``read_recording`` for phyphox exports too (the phyphox sniff and reader used to
open every .xlsx with openpyxl, and unpack zip members whole, before any cap)."""

from __future__ import annotations

import io
import struct
import zipfile

import pytest

from app.pipeline.ingestion import IngestionError, phyphox
from app.pipeline.ingestion.excel import MAX_ROWS
from app.pipeline.ingestion.messages import LANGUAGES
from app.pipeline.ingestion.session import read_recording

from tests.app.pipeline.ingestion.test_ingestion_xlsx_caps import SHEET, _rewrite_sheet, crafted_rows_xlsx

PHY_HEADER = ["Time (s)", "Acceleration x (m/s^2)", "Acceleration y (m/s^2)", "Acceleration z (m/s^2)"]


def _refused(paths) -> IngestionError:
    with pytest.raises(IngestionError) as exc:
        read_recording(paths)
    for lang in LANGUAGES:
        assert exc.value.message(lang) and "{" not in exc.value.message(lang)
    return exc.value


def test_the_crafted_workbook_is_refused_through_read_recording(tmp_path, monkeypatch):
    import openpyxl

    from app.pipeline.ingestion.xlsx_cells import Workbook
    opened = []
    monkeypatch.setattr(openpyxl, "load_workbook", lambda *a, **k: opened.append(a) or pytest.fail("opened"))
    for method in ("rows", "table"):   # the cell reader never parses a sheet of it
        monkeypatch.setattr(Workbook, method, lambda *a, **k: opened.append(a) or pytest.fail("parsed"))
    p = crafted_rows_xlsx(tmp_path / "step-muslo-X-01012024-1.xlsx")
    err = _refused([p])
    assert err.code == "xlsx.too_many_rows" and not opened  # refused before any sheet was parsed, sniff included


def test_a_phyphox_header_workbook_past_the_row_cap_is_refused(tmp_path):
    head = "".join(f'<c r="{chr(65 + i)}1" t="inlineStr"><is><t>{h}</t></is></c>' for i, h in enumerate(PHY_HEADER))
    xml = ('<?xml version="1.0" encoding="UTF-8" standalone="yes"?><worksheet '
           'xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"><sheetData>'
           f'<row r="1">{head}</row>' + "<row><c><v>1</v></c><c><v>0</v></c><c><v>0</v></c><c><v>9.8</v></c></row>"
           * (MAX_ROWS + 10) + "</sheetData></worksheet>").encode()
    p = tmp_path / "phone.xlsx"
    _rewrite_sheet(p, xml)
    assert p.stat().st_size < 200_000
    err = _refused([p])
    assert err.code == "xlsx.too_many_rows" and err.params["sheet"] == SHEET


def _phyphox_zip(path, big: bytes | None = None, member: str = "Accelerometer.csv"):
    header = ",".join(f'"{h}"' for h in PHY_HEADER) + "\n"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        z.writestr(member, header.encode() + (big or b"0.0,0.0,0.0,9.8\n"))
    return path


def test_a_zip_bomb_member_is_refused_from_its_declared_size(tmp_path, monkeypatch):
    p = _phyphox_zip(tmp_path / "phone.zip", b"0" * (phyphox.MAX_MEMBER_MB * 2**20 + 1))
    assert p.stat().st_size < 200_000
    monkeypatch.setattr(phyphox, "read_member", lambda *a, **k: pytest.fail("member unpacked"))
    err = _refused([p])
    assert err.code == "zip.too_big" and err.params["member"] == "Accelerometer.csv"
    assert err.params["limit_mb"] == phyphox.MAX_MEMBER_MB


def test_members_past_the_total_cap_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(phyphox, "MAX_ZIP_MB", 1)
    p = tmp_path / "phone.zip"
    header = (",".join(f'"{h}"' for h in PHY_HEADER) + "\n").encode()
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("A.csv", "B.csv", "C.csv"):
            z.writestr(name, header + b"0" * 400_000)
    err = _refused([p])
    assert err.code == "zip.too_big" and err.params["member"] == "(all)"


def _lie_about_size(data: bytes, declared: int) -> bytes:
    """The zip ``data`` with every header's uncompressed size set to ``declared``."""
    buf = bytearray(data)
    for sig, off in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):
        i = buf.find(sig)
        while i >= 0:
            struct.pack_into("<I", buf, i + off, declared)
            i = buf.find(sig, i + 4)
    return bytes(buf)


def test_a_lying_declared_size_is_caught_by_the_streamed_read(tmp_path, monkeypatch):
    monkeypatch.setattr(phyphox, "MAX_MEMBER_MB", 1)
    p = _phyphox_zip(tmp_path / "phone.zip", b"0" * (3 * 2**20))
    p.write_bytes(_lie_about_size(p.read_bytes(), 2**20))  # declares 1 MB (the cap), holds 3 MB
    assert zipfile.ZipFile(p).getinfo("Accelerometer.csv").file_size == 2**20
    err = _refused([p])  # passes the directory check; the read stops at the declaration (CRC) or the cap
    assert err.code in ("zip.too_big", "phone.member_unreadable")


def test_the_streamed_read_stops_at_the_cap_whatever_the_reader_returns(tmp_path):
    p = _phyphox_zip(tmp_path / "phone.zip")
    z = zipfile.ZipFile(p)
    reads = []

    class Endless(io.RawIOBase):  # a member reader that never ends (a declaration that lies)
        def read(self, n=-1):
            reads.append(n)
            return b"0" * n

    z.open = lambda member: Endless()
    with pytest.raises(IngestionError) as exc:
        phyphox.read_member(p, z, "Accelerometer.csv", limit_mb=2, chunk_bytes=1 << 18)
    assert exc.value.code == "zip.too_big" and sum(reads) == 2 * 2**20 + 1


def test_too_many_members_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(phyphox, "MAX_MEMBERS", 3)
    p = tmp_path / "phone.zip"
    header = (",".join(f'"{h}"' for h in PHY_HEADER) + "\n0,0,0,9.8\n").encode()
    with zipfile.ZipFile(p, "w") as z:
        for k in range(5):
            z.writestr(f"S{k}.csv", header)
    assert _refused([p]).code == "zip.too_many_members"


def test_a_sensor_logger_zip_bomb_is_refused_from_its_declared_size(tmp_path, monkeypatch):
    p = tmp_path / "phone.zip"
    head = b"time,seconds_elapsed,z,y,x\n1679000000000000000,0,0,0,9.8\n"
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        z.writestr("TotalAcceleration.csv", head + b"0" * (phyphox.MAX_MEMBER_MB * 2**20 + 1))
        z.writestr("Gyroscope.csv", head)
        z.writestr("Magnetometer.csv", head)
    from app.pipeline.ingestion import sensorlogger
    monkeypatch.setattr(sensorlogger, "read_member", lambda *a, **k: pytest.fail("member unpacked"))
    err = _refused([p])
    assert err.code == "zip.too_big" and err.params["member"] == "TotalAcceleration.csv"
