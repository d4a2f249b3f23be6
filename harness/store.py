"""The durable result store: one SQLite file, one row per record.

Each finished case is committed in its own transaction, so an interrupted run
loses nothing already finished. The file carries a ``meta`` table naming its
format, so a foreign or unreadable file is refused with a clear error instead
of being written to. WAL journaling lets several processes write one store.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pandas as pd

from harness.record import FIELDS, KEY_FIELDS
from harness.version import ROOT

DEFAULT_STORE = ROOT / "results" / "ibench.sqlite"
FORMAT = "integrator-bench-store"
FORMAT_VERSION = 1


class StoreError(RuntimeError):
    """The file is not a usable integrator-bench store."""


class Store:
    def __init__(self, path: Path | str = DEFAULT_STORE, create: bool = True):
        self.path = Path(path)
        if not self.path.exists():
            if not create:
                raise StoreError(f"store {self.path} does not exist")
            self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self.db = sqlite3.connect(self.path, timeout=60, isolation_level=None)
            self.db.execute("PRAGMA journal_mode=WAL")
            tables = {r[0] for r in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type='table'")}
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"store {self.path} is not a readable SQLite file: {exc}") from None
        if not tables:
            self._create()
        elif "meta" not in tables or dict(self.db.execute("SELECT key, value FROM meta")).get(
                "format") != FORMAT:
            raise StoreError(f"store {self.path} is a SQLite file of another program "
                             f"(no integrator-bench meta table)")

    def _create(self):
        cols = ", ".join(f"{name} {sqltype}" for name, sqltype in FIELDS.items())
        with self.db:
            self.db.execute("BEGIN")
            self.db.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")
            self.db.executemany("INSERT INTO meta VALUES (?, ?)",
                                [("format", FORMAT), ("version", str(FORMAT_VERSION))])
            self.db.execute(f"CREATE TABLE records (id INTEGER PRIMARY KEY AUTOINCREMENT, {cols})")
            self.db.execute("CREATE INDEX records_case ON records (case_id, code_version)")

    def add(self, record: dict) -> None:
        """Store one record, committed at once."""
        names = list(FIELDS)
        values = [_sql_value(record.get(n)) for n in names]
        self.db.execute(f"INSERT INTO records ({', '.join(names)}) VALUES "
                        f"({', '.join('?' * len(names))})", values)

    def done_case_ids(self, code_version: str) -> set[str]:
        """Case ids already stored for ``code_version``."""
        return {r[0] for r in self.db.execute(
            "SELECT DISTINCT case_id FROM records WHERE code_version = ?", (code_version,))}

    def dataframe(self) -> pd.DataFrame:
        """Every record, one row each, in insertion order."""
        df = pd.read_sql_query("SELECT * FROM records ORDER BY id", self.db)
        return df.drop(columns="id")

    def close(self):
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _sql_value(value):
    if value is None:
        return None
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    if hasattr(value, "item"):  # numpy scalars
        value = value.item()
    if isinstance(value, float) and value != value:
        return None
    return value


def load(path: Path | str = DEFAULT_STORE) -> pd.DataFrame:
    """The records of the store at ``path`` as a DataFrame."""
    with Store(path, create=False) as store:
        return store.dataframe()


__all__ = ["Store", "StoreError", "load", "DEFAULT_STORE", "KEY_FIELDS"]
