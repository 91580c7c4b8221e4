"""docs/architecture.md: "routes only parse, authorise and call". A route module makes no
query and no write of its own: no SQLAlchemy statement (`select(`, `delete(`, ...) and no
call on the request's database session (`db.execute`, `db.add`, `db.commit`, ...); the
study and analysis services do that.

The modules in `NOT_YET` still query for themselves (the architecture document says
so); the list may only shrink: a listed module that no longer queries fails the test
until it is taken off.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROUTES = Path(__file__).resolve().parents[3] / "backend" / "api" / "routes"
STATEMENTS = frozenset({"select", "delete", "update", "insert"})
SESSION_CALLS = frozenset({"execute", "scalars", "scalar", "add", "add_all", "delete",
                           "commit", "flush", "get", "refresh", "rollback", "merge"})
#: Route modules whose queries have not moved to a service yet.
NOT_YET: frozenset[str] = frozenset()


def queries(source: str) -> list[str]:
    """`line: call` of every query or write the module makes itself."""
    tree = ast.parse(source)
    from_sqlalchemy = {a.asname or a.name for node in ast.walk(tree)
                       if isinstance(node, ast.ImportFrom) and node.module
                       and node.module.split(".")[0] == "sqlalchemy" for a in node.names}
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if isinstance(f, ast.Name) and f.id in STATEMENTS & from_sqlalchemy:
            found.append(f"{node.lineno}: {f.id}(")
        elif (isinstance(f, ast.Attribute) and f.attr in SESSION_CALLS
              and isinstance(f.value, ast.Name) and f.value.id in ("db", "session")):
            found.append(f"{node.lineno}: {f.value.id}.{f.attr}(")
    return found


def test_the_checker_sees_a_query_and_a_write() -> None:
    src = ("from sqlalchemy import select\n"
           "def r(db):\n    db.add(x)\n    return db.scalars(select(T))\n")
    assert queries(src) == ["3: db.add(", "4: db.scalars(", "4: select("]
    assert queries("def r(db, svc):\n    return svc.list(db)\n") == []


def test_routes_make_no_queries_of_their_own() -> None:
    found = {p.stem: queries(p.read_text(encoding="utf-8"))
             for p in sorted(ROUTES.glob("*.py"))}
    offending = {m: q for m, q in found.items() if q and m not in NOT_YET}
    assert offending == {}, "move these to a service in backend/study or backend/analysis"
    assert sorted(m for m in NOT_YET if not found.get(m)) == [], \
        "these no longer query: take them off NOT_YET"
