"""DBC text of a one-message database for the protection tests."""

from __future__ import annotations

import cantools


def one_message_db(length: int, signals: str) -> cantools.database.Database:
    """A database of one message MSG (0x100, ``length`` bytes, sent by A every 10 ms) with the DBC lines
    ``signals``."""
    text = f"""VERSION ""
NS_ :
BS_:
BU_: A B
BO_ 256 MSG: {length} A
{signals}
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 10000;
BA_ "GenMsgCycleTime" BO_ 256 10;
"""
    db = cantools.database.load_string(text, "dbc", strict=False)
    assert isinstance(db, cantools.database.Database)
    return db
