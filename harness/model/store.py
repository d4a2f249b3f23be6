"""The durable result store: one SQLite file, one row per record.

Each finished case is committed in its own transaction, so an interrupted run
loses nothing already finished. The file carries a ``meta`` table naming its
format, so a foreign or unreadable file is refused with a clear error instead
of being written to. WAL journaling lets several processes write one store.
Writes are synchronous ``NORMAL`` (:data:`SYNCHRONOUS`), SQLite's advice for
WAL: a commit survives the process being killed or crashing, and only a power
loss or an operating-system crash may undo the last commits, never corrupt
the file; ``FULL`` waited for the disk at every case (4.5 ms a commit on the
project's machine, 9 s of the quick run's 2064 records, in which the
scheduling loop dispatched no case).
"""

from __future__ import annotations

import json
import os
import random
import sqlite3
import time
from pathlib import Path

import pandas as pd

from integrator_bench.harness.errors import StoreError
from integrator_bench.harness.paths import DEFAULT_STORE  # <data dir>/ibench.sqlite
from integrator_bench.harness.model.record import FIELDS, KEY_FIELDS, RUN_FIELDS

FORMAT = "integrator-bench-store"
FORMAT_VERSION = 2  # 2: runs table (provenance), records.run_id; older stores are upgraded
BUSY_TIMEOUT_S = 60.0  # how long opening or writing waits for another process holding the store
SYNCHRONOUS = "NORMAL"  # no disk flush per commit: durable unless the machine itself fails


class Store:
    """The store at ``path``; with ``create`` False, only an existing store is opened
    (a missing, empty or foreign file is refused with :class:`StoreError`, untouched)."""

    def __init__(self, path: Path | str = DEFAULT_STORE, create: bool = True):
        self.path = Path(path)
        _check_path(self.path, create)
        try:
            # Look before writing: a foreign SQLite file is refused untouched
            # (no WAL switch, no -wal file); a busy store waits up to BUSY_TIMEOUT_S.
            self.db = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
            tables = _tables(self.db)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"store {self.path} is not a readable SQLite file: {exc}") from None
        if tables and ("meta" not in tables or dict(self.db.execute(
                "SELECT key, value FROM meta")).get("format") != FORMAT):
            self.db.close()
            raise StoreError(f"store {self.path} is a SQLite file of another program "
                             f"(no integrator-bench meta table)")
        if not tables and not create:  # only a run makes a new store, never a reader
            self.db.close()
            raise StoreError(f"store {self.path} is empty, not an integrator-bench store")
        try:
            self._set_up()
        except sqlite3.DatabaseError as exc:
            self.db.close()
            raise StoreError(f"store {self.path} cannot be written: {exc}") from None

    def _set_up(self):
        """Switch to WAL and create or upgrade the tables, retrying while another
        process does the same.

        SQLite answers "database is locked" at once, without waiting in the busy
        handler, when waiting could deadlock: two processes that both read the
        new file and then both want to write it (one switching to WAL, the other
        creating the tables). The loser's locks are released, so it retries.
        """
        deadline = time.monotonic() + BUSY_TIMEOUT_S
        while True:
            try:
                self.db.execute("PRAGMA journal_mode=WAL")
                self.db.execute(f"PRAGMA synchronous={SYNCHRONOUS}")
                self._create_or_upgrade()
                return
            except sqlite3.OperationalError as exc:
                busy = "locked" in str(exc) or "busy" in str(exc)
                if not busy or time.monotonic() > deadline:
                    raise
                time.sleep(random.uniform(0.01, 0.1))

    def _create_or_upgrade(self):
        """Create the tables, or add what an older format lacks.

        One IMMEDIATE transaction, so two processes opening a new or old store
        at once do not race; every statement is idempotent.
        """
        cols = ", ".join(f"{name} {sqltype}" for name, sqltype in FIELDS.items())
        self.db.execute("BEGIN IMMEDIATE")
        try:
            self.db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
            self.db.execute("INSERT OR IGNORE INTO meta VALUES ('format', ?)", (FORMAT,))
            self.db.execute(f"CREATE TABLE IF NOT EXISTS records "
                            f"(id INTEGER PRIMARY KEY AUTOINCREMENT, {cols})")
            self.db.execute("CREATE INDEX IF NOT EXISTS records_case "
                            "ON records (case_id, code_version)")
            runs = ", ".join(f"{name} {sqltype}" for name, sqltype in RUN_FIELDS.items())
            self.db.execute(f"CREATE TABLE IF NOT EXISTS runs ({runs})")
            for table, fields in (("records", FIELDS), ("runs", RUN_FIELDS)):
                have = {r[1] for r in self.db.execute(f"PRAGMA table_info({table})")}
                for name, sqltype in fields.items():
                    if name not in have:  # a store written before the field existed
                        sqltype = sqltype.replace(" PRIMARY KEY", "")
                        self.db.execute(f"ALTER TABLE {table} ADD COLUMN {name} {sqltype}")
            self.db.execute("INSERT OR REPLACE INTO meta VALUES ('version', ?)",
                            (str(FORMAT_VERSION),))
            self.db.execute("COMMIT")
        except BaseException:
            self.db.execute("ROLLBACK")
            raise

    def add(self, record: dict, once: bool = False, skip_policy: str | None = None) -> bool:
        """Store one record, committed at once (one statement, one transaction).

        With ``once``, the record is left out when the store already holds its
        case for its code version (the resume key) as done (:meth:`done_case_ids`
        under ``skip_policy``), checked and inserted in the same statement: two
        resumed runs of one matrix never store a case twice.
        Returns whether it was stored.
        """
        names = list(FIELDS)
        values = [_sql_value(record.get(n)) for n in names]
        sql = (f"INSERT INTO records ({', '.join(names)}) "
               f"SELECT {', '.join('?' * len(names))}")
        if once:
            sql += (" WHERE NOT EXISTS (SELECT 1 FROM records "
                    f"WHERE case_id = ? AND code_version IS ? AND {_DONE})")
            values += [record.get("case_id"), record.get("code_version"), skip_policy]
        return self.db.execute(sql, values).rowcount == 1

    def begin_run(self, provenance: dict) -> str:
        """Store a new run's provenance (see :mod:`integrator_bench.harness.model.provenance`); return its id."""
        row = {k: _sql_value(provenance.get(k)) for k in RUN_FIELDS}
        self.db.execute(f"INSERT INTO runs ({', '.join(row)}) VALUES "
                        f"({', '.join('?' * len(row))})", list(row.values()))
        return provenance["run_id"]

    def finish_run(self, run_id: str, status: str, finished: str) -> None:
        """Mark a run ``finished`` or ``interrupted`` (a killed run keeps null)."""
        self.db.execute("UPDATE runs SET status = ?, finished = ? WHERE run_id = ?",
                        (status, finished, run_id))

    def runs(self) -> pd.DataFrame:
        """Every run's provenance, oldest first."""
        return pd.read_sql_query(f"SELECT {', '.join(RUN_FIELDS)} FROM runs ORDER BY started",
                                 self.db)

    def done_case_ids(self, code_version: str, skip_policy: str | None = None) -> set[str]:
        """Case ids already stored for ``code_version``: a ``skipped`` record
        counts only when it was skipped under ``skip_policy`` (None: a run that
        skips nothing, for which no skipped record is done)."""
        return {r[0] for r in self.db.execute(
            f"SELECT DISTINCT case_id FROM records WHERE code_version = ? AND {_DONE}",
            (code_version, skip_policy))}

    def measured(self) -> list[dict]:
        """The key and CPU of every ``ok`` record with a positive CPU, any code
        version: what the scheduler's cost model is fitted on."""
        cur = self.db.execute("SELECT problem, params, integrator, rtol, h, cpu_s FROM records "
                              "WHERE status = 'ok' AND cpu_s > 0")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, row)) for row in cur]

    def dataframe(self) -> pd.DataFrame:
        """Every record, one row each, in insertion order."""
        return pd.read_sql_query(f"SELECT {', '.join(FIELDS)} FROM records ORDER BY id",
                                 self.db)

    def close(self):
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# a stored record is done for a resumed run unless it was skipped under other rules
_DONE = "(status IS NOT 'skipped' OR skip_policy IS ?)"


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


def _tables(db) -> set[str]:
    return {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}


def _check_path(path: Path, create: bool) -> None:
    """Refuse, before anything is written, a path that cannot be a store."""
    if path.exists():
        if not path.is_file():
            raise StoreError(f"store {path} is not a file")
        if not os.access(path, os.R_OK | os.W_OK):
            raise StoreError(f"store {path} is not readable and writable")
        return
    if not create:
        raise StoreError(f"store {path} does not exist")
    parent = path.parent
    if not parent.is_dir():
        raise StoreError(f"cannot create store {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise StoreError(f"cannot create store {path}: directory {parent} is not writable")


def load(path: Path | str = DEFAULT_STORE) -> pd.DataFrame:
    """The records of the store at ``path`` as a DataFrame."""
    with Store(path, create=False) as store:
        return store.dataframe()


def load_runs(path: Path | str = DEFAULT_STORE) -> pd.DataFrame:
    """The runs (provenance) of the store at ``path`` as a DataFrame."""
    with Store(path, create=False) as store:
        return store.runs()


__all__ = ["Store", "StoreError", "load", "load_runs", "DEFAULT_STORE", "KEY_FIELDS"]
