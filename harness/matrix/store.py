"""The durable result store: one SQLite file, one row per record.

Each finished case is committed in its own transaction, so an interrupted run
loses nothing already finished. The file carries a ``meta`` table naming its
format, so a foreign or unreadable file is refused with a clear error instead
of being written to. WAL journaling lets several processes write one store.
Writes are synchronous ``NORMAL`` (:data:`SYNCHRONOUS`), SQLite's advice for
WAL: a commit survives the process being killed or crashing, and only a power
loss or an operating-system crash may undo the last commits, never corrupt
the file; ``FULL`` waits for the disk at every case, during which the
scheduling loop dispatches none (docs/timing.md, "Measurements behind the code").
"""

from __future__ import annotations

import json
import os
import random
import sqlite3
import time
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from integrator_bench.harness.errors import StoreError
from integrator_bench.harness.paths import DEFAULT_STORE  # <data dir>/ibench.sqlite
from integrator_bench.harness.matrix.line import KEY_FIELDS, backfill
from integrator_bench.harness.matrix.provenance import backfill_runs
from integrator_bench.harness.matrix.record import FIELDS, RUN_FIELDS

FORMAT = "integrator-bench-store"
FORMAT_VERSION = 2  # 2: runs table (provenance), records.run_id; older stores are upgraded
BUSY_TIMEOUT_S = 60.0  # how long opening or writing waits for another process holding the store
SYNCHRONOUS = "NORMAL"  # no disk flush per commit: durable unless the machine itself fails


class Store:
    """The store at ``path``.

    With ``create`` (a run) the store is made when missing, switched to WAL and
    upgraded from an older format. Without it (a reader: ``report``, ``stiffness``)
    only an existing store is opened, read-only (SQLite's ``mode=ro``, and
    ``immutable`` when no writer has it open: :func:`_read_only_uri`), so a
    read-only file can be reported and nothing is ever written, not even a
    ``-wal`` file beside it. Either way, a file that
    cannot be a store is refused with :class:`StoreError` before anything is
    written to it, left byte for byte as it was: a missing (for a reader), empty
    (for a reader) or foreign file, one whose ``records`` table is not a store's,
    and one of a newer format version ("written by a newer integrator-bench").
    """

    def __init__(self, path: Path | str = DEFAULT_STORE, create: bool = True):
        self.path = Path(path)
        self.readonly = not create
        _check_path(self.path, create)
        try:
            # Look before writing: a foreign SQLite file is refused untouched
            # (no WAL switch, no -wal file); a busy store waits up to BUSY_TIMEOUT_S.
            self.db, tables = _open(self.path, self.readonly)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"store {self.path} is not a readable SQLite file: {exc}") from None
        try:
            why = _refusal(self.db, tables)
        except sqlite3.DatabaseError as exc:
            why = f"is not a readable SQLite file: {exc}"
        if why is None and not tables and not create:  # only a run makes a new store
            why = "is empty, not an integrator-bench store"
        if why is not None:
            self.db.close()
            raise StoreError(f"store {self.path} {why}")
        if self.readonly:
            return
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
        return self._write(sql, values).rowcount == 1

    def _write(self, sql: str, values):
        """Execute the writing statement ``sql``; a write SQLite cannot make (a full
        disk, a file made read-only, an I/O error) is :class:`StoreError` naming
        the store."""
        try:
            return self.db.execute(sql, values)
        except sqlite3.OperationalError as exc:
            raise StoreError(f"store {self.path} cannot be written: {exc}") from None

    def begin_run(self, provenance: dict) -> str:
        """Store a new run's provenance (see :mod:`integrator_bench.harness.matrix.provenance`); return its id."""
        row = {k: _sql_value(provenance.get(k)) for k in RUN_FIELDS}
        self._write(f"INSERT INTO runs ({', '.join(row)}) VALUES "
                    f"({', '.join('?' * len(row))})", list(row.values()))
        return provenance["run_id"]

    def finish_run(self, run_id: str, status: str, finished: str,
                   options: dict | None = None) -> None:
        """Mark a run ``finished`` or ``interrupted`` (a killed run keeps null), and
        give it its ``options`` when they are known only at its end (a run of
        several batches: an advice's rounds)."""
        self._write("UPDATE runs SET status = ?, finished = ? WHERE run_id = ?",
                    (status, finished, run_id))
        if options is not None:
            self._write("UPDATE runs SET options = ? WHERE run_id = ?",
                        (_sql_value(options), run_id))

    def runs(self) -> pd.DataFrame:
        """Every run's provenance, oldest first (none in a format-1 store); a
        run's ``purpose`` filled in where a store written before that field lacks
        it (:func:`~integrator_bench.harness.matrix.provenance.backfill_runs`)."""
        return backfill_runs(self._select("runs", RUN_FIELDS, "started"))

    def done_case_ids(self, code_version: str, skip_policy: str | None = None) -> set[str]:
        """Case ids already stored for ``code_version``: a ``skipped`` or
        ``dominated`` record counts only when it was decided under ``skip_policy``
        (None: a run that skips nothing and races nothing, for which no such record
        is done)."""
        return {r[0] for r in self.db.execute(
            f"SELECT DISTINCT case_id FROM records WHERE code_version = ? AND {_DONE}",
            (code_version, skip_policy))}

    def measured(self) -> list[dict]:
        """The key and CPU of every ``ok`` or ``failed`` record with a positive CPU,
        and of every ``timeout`` at its budget (at least), any code version: what
        the scheduler's cost model and a run's plan are fitted on (what a case
        cost, whatever its outcome)."""
        cur = self.db.execute(
            "SELECT problem, params, formulation, integrator, rtol, h, CASE WHEN status = "
            "'timeout' THEN max(coalesce(cpu_s, 0), budget_s) ELSE cpu_s END AS cpu_s "
            "FROM records WHERE (status IN ('ok', 'failed') AND cpu_s > 0) "
            "OR (status = 'timeout' AND budget_s > 0)")
        names = [d[0] for d in cur.description]
        return [dict(zip(names, row)) for row in cur]

    def dataframe(self) -> pd.DataFrame:
        """Every record, one row each, in insertion order; the fields of its line a
        record of an older store lacks (mode, line, label, family) filled in
        (:func:`~integrator_bench.harness.matrix.line.backfill`), so every reader
        sees them."""
        return backfill(self._select("records", FIELDS, "id"))

    def _select(self, table: str, fields: dict, order: str) -> pd.DataFrame:
        """Every row of ``table`` with a column per field, in ``order``; a field an
        older store (read, not upgraded) lacks is null, a table it lacks empty."""
        have = {r[1] for r in self.db.execute(f"PRAGMA table_info({table})")}
        if not have:
            return pd.DataFrame(columns=list(fields))
        columns = [name if name in have else f"NULL AS {name}" for name in fields]
        return pd.read_sql_query(f"SELECT {', '.join(columns)} FROM {table} ORDER BY "
                                 f"{order if order in have else 'rowid'}", self.db)

    def close(self):
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# a stored record is done for a resumed run unless it was skipped under other rules
_DONE = "(status NOT IN ('skipped', 'dominated') OR skip_policy IS ?)"


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


#: the columns without which a ``records`` table is not a store's (older formats have them)
RECORD_KEY_COLUMNS = ("id", "case_id", "code_version")


def _open(path: Path, readonly: bool):
    """``(connection, its tables)``; for a reader read-only (see :func:`_read_only_uri`)."""
    if not readonly:
        db = sqlite3.connect(path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
    else:
        db = sqlite3.connect(_read_only_uri(path), uri=True, timeout=BUSY_TIMEOUT_S,
                             isolation_level=None)
    try:
        return db, _tables(db)
    except BaseException:
        db.close()
        raise


def _read_only_uri(path: Path) -> str:
    """The URI a reader opens ``path`` by: ``mode=ro``; for a store in WAL mode
    with no ``-wal`` file beside it (no writer has it open, everything is in the
    file) also ``immutable=1``, since a read-only connection would otherwise make
    the ``-wal`` and ``-shm`` files (and cannot, beside a read-only file in a
    read-only folder). A writer that opens the store meanwhile writes into its
    new ``-wal``, which such a reader does not see."""
    uri = f"file:{quote(str(path.absolute()))}?mode=ro"
    try:
        with open(path, "rb") as f:
            wal = f.read(20)[18:20] == b"\x02\x02"   # file format versions: 2 is WAL
    except OSError:
        wal = False
    if wal and not Path(f"{path}-wal").exists():
        uri += "&immutable=1"
    return uri


def _refusal(db, tables: set[str]) -> str | None:
    """Why the SQLite file ``db`` cannot be used as a store (what follows "store
    PATH "), or None; reads only."""
    if not tables:
        return None
    meta = dict(db.execute("SELECT key, value FROM meta")) if "meta" in tables else {}
    if meta.get("format") != FORMAT:
        return "is a SQLite file of another program (no integrator-bench meta table)"
    try:
        version = int(meta.get("version", "1"))
    except ValueError:
        return f"has an unreadable format version {meta.get('version')!r}"
    if version > FORMAT_VERSION:
        return (f"was written by a newer integrator-bench (store format {version}; this "
                f"one reads up to {FORMAT_VERSION}): upgrade integrator-bench to use it")
    if "records" in tables:
        have = {r[1] for r in db.execute("PRAGMA table_info(records)")}
        missing = [c for c in RECORD_KEY_COLUMNS if c not in have]
        if missing:
            return (f"has a records table that is not integrator-bench's (no column "
                    f"{', '.join(missing)})")
    return None


def _check_path(path: Path, create: bool) -> None:
    """Refuse, before anything is written, a path that cannot be a store (a
    reader needs only to read it)."""
    if path.exists():
        if not path.is_file():
            raise StoreError(f"store {path} is not a file")
        if not os.access(path, os.R_OK if not create else os.R_OK | os.W_OK):
            raise StoreError(f"store {path} is not readable"
                             + ("" if not create else " and writable"))
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
