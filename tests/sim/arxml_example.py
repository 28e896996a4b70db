"""How dbc/examples/arxml/tcu.arxml is made from the shipped DBC (tests/sim/test_arxml_matrix.py checks that the file
is this function's text): the DBC's messages but the simulation-only ones, each PDU's signals moved behind an E2E
header (Profile 5: CRC bytes 0-1, counter byte 2; Profile 11: CRC byte 0, counter bits 8-11), the DBC's Counter
and CRC signals and TCU_CMD's DecelRequest (it does not fit behind the Profile 5 header) left out; scalings, ranges
and units as LINEAR compu methods, VAL_ tables as TEXTTABLE ones, cycle times as I-PDU timings.

Regenerate: ``python tests/sim/arxml_example.py > dbc/examples/arxml/tcu.arxml`` (then copy it to
dsg_hil/data/examples/arxml/)."""

from __future__ import annotations

import sys
from xml.sax.saxutils import escape

from cantools.database.can import Database, Message, Signal

E2E = {"TCU_CMD": ("PROFILE_05", 0x1200), "TCU_STATUS": ("PROFILE_05", 0x1210),
       **{name: ("PROFILE_11", 0x0100 + i) for i, name in enumerate(
           ["PLANT_ENGINE", "PLANT_SPEEDS", "PLANT_VEHICLE", "PLANT_PRESSURE", "PLANT_OIL_TEMP", "DRIVER"])}}
LEFT_OUT = {("TCU_CMD", "DecelRequest")}
HEADER = """<!-- An example AUTOSAR 4 system description of a TCU's CAN bus, for "Connect your ECU": the messages of
     dbc/dsg_hil.dbc but the simulation-only ones (the binding adds SIM_SYNC from the simulation database), their
     signals moved behind an E2E header: AUTOSAR E2E Profile 5 (CRC bytes 0-1, counter byte 2) on TCU_CMD and
     TCU_STATUS, Profile 11 (11A: CRC byte 0, counter the low nibble of byte 1) on the plant's frames, with data IDs
     0x1200, 0x1210 and 0x0100-0x0105. TCU_CMD has no DecelRequest (it does not fit behind the Profile 5 header).
     Written by tests/sim/arxml_example.py from the DBC; tcu.binding.toml binds the plant to it. -->"""


def _layout(message: Message) -> tuple[list[tuple[str, int, int]], list[tuple[Signal, int]]]:
    """(the E2E header's signals: name, start, length; the message's signals with their new start bits)."""
    profile = E2E[message.name][0]
    head = [("Crc", 0, 16), ("Counter", 16, 8)] if profile == "PROFILE_05" else [("Crc", 0, 8), ("Counter", 8, 4)]
    position = 24 if profile == "PROFILE_05" else 16
    placed = []
    for signal in message.signals:
        if signal.name in ("Counter", "CRC") or (message.name, signal.name) in LEFT_OUT:
            continue
        placed.append((signal, position))
        position += signal.length
    assert position <= 64, (message.name, position)
    return head, placed


def arxml_from_dbc(db: Database) -> str:
    """The ARXML text of ``db``'s messages named in :data:`E2E`."""
    names = list(E2E)
    units: dict[str, str] = {}
    out = ['<?xml version="1.0" encoding="UTF-8"?>', HEADER, '<AUTOSAR xmlns="http://autosar.org/schema/r4.0">',
           "  <AR-PACKAGES>"]
    w = out.append
    w("    <AR-PACKAGE><SHORT-NAME>Cluster</SHORT-NAME><ELEMENTS><CAN-CLUSTER><SHORT-NAME>Bus</SHORT-NAME>")
    w("      <CAN-CLUSTER-VARIANTS><CAN-CLUSTER-CONDITIONAL><BAUDRATE>500000</BAUDRATE><PHYSICAL-CHANNELS>")
    w("      <CAN-PHYSICAL-CHANNEL><SHORT-NAME>Channel</SHORT-NAME><FRAME-TRIGGERINGS>")
    for n in names:
        m = db.get_message_by_name(n)
        w(f"        <CAN-FRAME-TRIGGERING><SHORT-NAME>{n}</SHORT-NAME><FRAME-REF DEST=\"CAN-FRAME\">/Frames/{n}"
          f"</FRAME-REF><CAN-ADDRESSING-MODE>STANDARD</CAN-ADDRESSING-MODE><IDENTIFIER>{m.frame_id}</IDENTIFIER>"
          f"</CAN-FRAME-TRIGGERING>")
    w("      </FRAME-TRIGGERINGS></CAN-PHYSICAL-CHANNEL></PHYSICAL-CHANNELS></CAN-CLUSTER-CONDITIONAL>")
    w("      </CAN-CLUSTER-VARIANTS></CAN-CLUSTER></ELEMENTS></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>Frames</SHORT-NAME><ELEMENTS>")
    for n in names:
        w(f"      <CAN-FRAME><SHORT-NAME>{n}</SHORT-NAME><FRAME-LENGTH>8</FRAME-LENGTH><PDU-TO-FRAME-MAPPINGS>"
          f"<PDU-TO-FRAME-MAPPING><SHORT-NAME>{n}</SHORT-NAME><PACKING-BYTE-ORDER>MOST-SIGNIFICANT-BYTE-LAST"
          f"</PACKING-BYTE-ORDER><PDU-REF DEST=\"I-SIGNAL-I-PDU\">/PDUs/{n}</PDU-REF><START-POSITION>0"
          f"</START-POSITION></PDU-TO-FRAME-MAPPING></PDU-TO-FRAME-MAPPINGS></CAN-FRAME>")
    w("    </ELEMENTS></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>PDUs</SHORT-NAME><ELEMENTS>")
    layouts = {n: _layout(db.get_message_by_name(n)) for n in names}  # each message's placing, once
    for n in names:
        m = db.get_message_by_name(n)
        head, placed = layouts[n]
        w(f"      <I-SIGNAL-I-PDU><SHORT-NAME>{n}</SHORT-NAME><LENGTH>8</LENGTH>")
        w(f"        <I-PDU-TIMING-SPECIFICATIONS><I-PDU-TIMING><TRANSMISSION-MODE-DECLARATION>"
          f"<TRANSMISSION-MODE-TRUE-TIMING><CYCLIC-TIMING><TIME-PERIOD><VALUE>{(m.cycle_time or 0) / 1000:g}"
          f"</VALUE></TIME-PERIOD></CYCLIC-TIMING></TRANSMISSION-MODE-TRUE-TIMING></TRANSMISSION-MODE-DECLARATION>"
          f"</I-PDU-TIMING></I-PDU-TIMING-SPECIFICATIONS>")
        w("        <I-SIGNAL-TO-PDU-MAPPINGS>")
        for sname, start in [(h[0], h[1]) for h in head] + [(s.name, p) for s, p in placed]:
            w(f"          <I-SIGNAL-TO-I-PDU-MAPPING><SHORT-NAME>{sname}</SHORT-NAME><I-SIGNAL-REF DEST=\"I-SIGNAL\">"
              f"/Signals/{n}/{sname}</I-SIGNAL-REF><PACKING-BYTE-ORDER>MOST-SIGNIFICANT-BYTE-LAST"
              f"</PACKING-BYTE-ORDER><START-POSITION>{start}</START-POSITION></I-SIGNAL-TO-I-PDU-MAPPING>")
        w("        </I-SIGNAL-TO-PDU-MAPPINGS></I-SIGNAL-I-PDU>")
    w("    </ELEMENTS></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>Signals</SHORT-NAME><AR-PACKAGES>")
    for n in names:
        head, placed = layouts[n]
        w(f"      <AR-PACKAGE><SHORT-NAME>{n}</SHORT-NAME><ELEMENTS>")
        for sname, _, length in head:
            w(f"        <I-SIGNAL><SHORT-NAME>{sname}</SHORT-NAME><LENGTH>{length}</LENGTH></I-SIGNAL>")
        for s, _ in placed:
            base = "Signed" if s.is_signed else "Unsigned"
            w(f"        <I-SIGNAL><SHORT-NAME>{s.name}</SHORT-NAME><LENGTH>{s.length}</LENGTH>"
              f"<NETWORK-REPRESENTATION-PROPS><SW-DATA-DEF-PROPS-VARIANTS><SW-DATA-DEF-PROPS-CONDITIONAL>"
              f"<BASE-TYPE-REF DEST=\"SW-BASE-TYPE\">/Types/{base}</BASE-TYPE-REF></SW-DATA-DEF-PROPS-CONDITIONAL>"
              f"</SW-DATA-DEF-PROPS-VARIANTS></NETWORK-REPRESENTATION-PROPS>"
              f"<SYSTEM-SIGNAL-REF DEST=\"SYSTEM-SIGNAL\">/SystemSignals/{n}/{s.name}</SYSTEM-SIGNAL-REF></I-SIGNAL>")
        w("      </ELEMENTS></AR-PACKAGE>")
    w("    </AR-PACKAGES></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>SystemSignals</SHORT-NAME><AR-PACKAGES>")
    for n in names:
        _, placed = layouts[n]
        w(f"      <AR-PACKAGE><SHORT-NAME>{n}</SHORT-NAME><ELEMENTS>")
        for s, _ in placed:
            w(f"        <SYSTEM-SIGNAL><SHORT-NAME>{s.name}</SHORT-NAME><PHYSICAL-PROPS><SW-DATA-DEF-PROPS-VARIANTS>"
              f"<SW-DATA-DEF-PROPS-CONDITIONAL><COMPU-METHOD-REF DEST=\"COMPU-METHOD\">/CompuMethods/{n}/{s.name}"
              f"</COMPU-METHOD-REF></SW-DATA-DEF-PROPS-CONDITIONAL></SW-DATA-DEF-PROPS-VARIANTS></PHYSICAL-PROPS>"
              f"</SYSTEM-SIGNAL>")
        w("      </ELEMENTS></AR-PACKAGE>")
    w("    </AR-PACKAGES></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>CompuMethods</SHORT-NAME><AR-PACKAGES>")
    for n in names:
        _, placed = layouts[n]
        w(f"      <AR-PACKAGE><SHORT-NAME>{n}</SHORT-NAME><ELEMENTS>")
        for s, _ in placed:
            if s.choices:  # the DBC's VAL_ table: a TEXTTABLE (cantools reads it as the signal's choices)
                scales = "".join(f"<COMPU-SCALE><LOWER-LIMIT>{v}</LOWER-LIMIT><UPPER-LIMIT>{v}</UPPER-LIMIT>"
                                 f"<COMPU-CONST><VT>{c}</VT></COMPU-CONST></COMPU-SCALE>" for v, c in s.choices.items())
                w(f"        <COMPU-METHOD><SHORT-NAME>{s.name}</SHORT-NAME><CATEGORY>TEXTTABLE</CATEGORY>"
                  f"<COMPU-INTERNAL-TO-PHYS><COMPU-SCALES>{scales}</COMPU-SCALES></COMPU-INTERNAL-TO-PHYS>"
                  f"</COMPU-METHOD>")
                continue
            assert s.minimum is not None and s.maximum is not None, s.name
            lo, hi = (round((x - s.offset) / s.scale) for x in (s.minimum, s.maximum))  # the DBC's range, raw
            unit = s.unit if s.unit not in (None, "", "-") else None
            reference = ""
            if unit:
                units.setdefault(unit, f"U{len(units)}")
                reference = f"<UNIT-REF DEST=\"UNIT\">/Units/{units[unit]}</UNIT-REF>"
            w(f"        <COMPU-METHOD><SHORT-NAME>{s.name}</SHORT-NAME><CATEGORY>LINEAR</CATEGORY>{reference}"
              f"<COMPU-INTERNAL-TO-PHYS><COMPU-SCALES><COMPU-SCALE><LOWER-LIMIT>{lo}</LOWER-LIMIT>"
              f"<UPPER-LIMIT>{hi}</UPPER-LIMIT><COMPU-RATIONAL-COEFFS><COMPU-NUMERATOR><V>{s.offset:g}</V>"
              f"<V>{s.scale:g}</V></COMPU-NUMERATOR><COMPU-DENOMINATOR><V>1</V></COMPU-DENOMINATOR>"
              f"</COMPU-RATIONAL-COEFFS></COMPU-SCALE></COMPU-SCALES></COMPU-INTERNAL-TO-PHYS></COMPU-METHOD>")
        w("      </ELEMENTS></AR-PACKAGE>")
    w("    </AR-PACKAGES></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>Units</SHORT-NAME><ELEMENTS>")
    for unit, key in units.items():
        w(f"      <UNIT><SHORT-NAME>{key}</SHORT-NAME><DISPLAY-NAME>{escape(unit)}</DISPLAY-NAME></UNIT>")
    w("    </ELEMENTS></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>Types</SHORT-NAME><ELEMENTS>")
    w("      <SW-BASE-TYPE><SHORT-NAME>Unsigned</SHORT-NAME><BASE-TYPE-ENCODING>NONE</BASE-TYPE-ENCODING>"
      "</SW-BASE-TYPE>")
    w("      <SW-BASE-TYPE><SHORT-NAME>Signed</SHORT-NAME><BASE-TYPE-ENCODING>2C</BASE-TYPE-ENCODING></SW-BASE-TYPE>")
    w("    </ELEMENTS></AR-PACKAGE>")
    w("    <AR-PACKAGE><SHORT-NAME>E2E</SHORT-NAME><ELEMENTS><END-TO-END-PROTECTION-SET><SHORT-NAME>Protections"
      "</SHORT-NAME><END-TO-END-PROTECTIONS>")
    for n in names:
        category, data_id = E2E[n]
        w(f"      <END-TO-END-PROTECTION><SHORT-NAME>{n}</SHORT-NAME><END-TO-END-PROFILE><CATEGORY>{category}"
          f"</CATEGORY><DATA-IDS><DATA-ID>{data_id}</DATA-ID></DATA-IDS></END-TO-END-PROFILE>"
          f"<END-TO-END-PROTECTION-I-SIGNAL-I-PDUS><END-TO-END-PROTECTION-I-SIGNAL-I-PDU><I-SIGNAL-I-PDU-REF "
          f"DEST=\"I-SIGNAL-I-PDU\">/PDUs/{n}</I-SIGNAL-I-PDU-REF></END-TO-END-PROTECTION-I-SIGNAL-I-PDU>"
          f"</END-TO-END-PROTECTION-I-SIGNAL-I-PDUS></END-TO-END-PROTECTION>")
    w("    </END-TO-END-PROTECTIONS></END-TO-END-PROTECTION-SET></ELEMENTS></AR-PACKAGE>")
    w("  </AR-PACKAGES>")
    w("</AUTOSAR>")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    from dsg_hil.protocol import load_dbc

    sys.stdout.write(arxml_from_dbc(load_dbc()))
