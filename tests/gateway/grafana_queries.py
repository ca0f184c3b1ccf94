"""Runs Grafana's queries of loopwire's history against a real PostgreSQL, as Grafana would.

Every ```sql block of docs/grafana.md, every panel target's rawSql and every query variable of
the dashboard JSON is expanded the way Grafana's PostgreSQL data source expands it, over the last
hour: $__timeFilter(col) -> col BETWEEN 'from' AND 'to' (RFC 3339), $__unixEpochFrom() and
$__unixEpochTo() -> seconds, and the multi-value variables $gateway, $device, $parameter -> quoted
lists of what the historian holds (all of them, as "All" selects). Each panel query and each
documented query must answer rows of both gateways (north and south), each variable query the
values it lists.

usage: grafana_queries.py DOC.md DASHBOARD.json PG_HOST PG_PORT DATABASE
"""
import json
import re
import subprocess
import sys
import time

doc, dashboard_file, host, port, database = sys.argv[1:6]


def psql(sql):
    done = subprocess.run(["psql", "-X", "-qAt", "-F", "\t", "-v", "ON_ERROR_STOP=1", "-h", host, "-p", port,
                           "-U", "postgres", "-d", database, "-c", sql], capture_output=True, text=True, timeout=30)
    if done.returncode != 0:
        sys.exit(f"query failed: {done.stderr.strip()}\n{sql}")
    return [line.split("\t") for line in done.stdout.splitlines()]


now = time.time()
start, end = now - 3600, now + 60


def rfc3339(seconds):
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(seconds))


def quoted(values):
    return ",".join("'" + v.replace("'", "''") + "'" for v in values)


variables = {
    "gateway": [r[0] for r in psql("SELECT DISTINCT gateway FROM loopwire_series ORDER BY 1")],
    "device": [r[0] for r in psql("SELECT DISTINCT device FROM loopwire_series ORDER BY 1")],
    "parameter": [r[0] for r in psql("SELECT DISTINCT parameter FROM loopwire_series ORDER BY 1")],
}
assert variables["gateway"] == ["north", "south"], variables


def expand(sql):
    sql = re.sub(r"\$__timeFilter\((\w+)\)", lambda m: f"{m.group(1)} BETWEEN '{rfc3339(start)}' AND '{rfc3339(end)}'", sql)
    sql = sql.replace("$__unixEpochFrom()", str(int(start))).replace("$__unixEpochTo()", str(int(end)))
    for name, values in variables.items():
        sql = sql.replace(f"${name}", quoted(values))
    assert "$" not in sql, f"unexpanded macro or variable in:\n{sql}"
    return sql


def check_rows(where, sql, columns_with_gateway):
    rows = psql(expand(sql))
    assert rows, f"{where}: no rows"
    text = "\n".join("\t".join(r) for r in rows)
    if columns_with_gateway:
        for gateway in ("north", "south"):
            assert gateway in text, f"{where}: no row of {gateway}:\n{text[:500]}"
    print(f"ok: {where}: {len(rows)} rows")


documented = re.findall(r"```sql\n(.*?)```", open(doc).read(), re.S)
assert len(documented) >= 4, f"expected the documented queries in {doc}"
for i, sql in enumerate(documented, 1):
    if "status <> 'ok'" in sql:
        # Values that were not ok: a virtual line's TC10 answers every poll, so there may be none;
        # the query must still run.
        psql(expand(sql))
        print(f"ok: {doc} query {i} runs")
        continue
    # Without a gateway column in its result the rows still come from both (metric names them or not).
    check_rows(f"{doc} query {i}", sql, "gateway ||" in sql or "gateway," in sql)

dashboard = json.load(open(dashboard_file))
for variable in dashboard["templating"]["list"]:
    listed = [r[0] for r in psql(expand(variable["query"]))]
    assert listed == variables[variable["name"]], f"variable {variable['name']}: {listed}"
    print(f"ok: variable {variable['name']}: {listed}")
for panel in dashboard["panels"]:
    for target in panel["targets"]:
        if "status <> 'ok'" in target["rawSql"]:
            psql(expand(target["rawSql"]))
            print(f"ok: panel {panel['title']!r} runs")
            continue
        check_rows(f"panel {panel['title']!r}", target["rawSql"], True)
