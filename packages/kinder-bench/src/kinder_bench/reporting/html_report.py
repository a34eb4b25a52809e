"""``kinder bench report --html``: one self-contained HTML page for a set of runs.

The page has no external resource (inline CSS and JavaScript, images and videos as ``data:``
URIs, and a Content-Security-Policy that forbids loading anything else), so it can be mailed,
archived or opened offline. It shows:

* filters by env and by method (checkboxes; they apply to everything below),
* the results table (one row per env × method: SR, Rwd on successes, Inf-Time, each mean ± std
  over seeds, and the paper's value beside ours only for a run at the paper's protocol; any other
  run is a variant named by what differs, as in :mod:`kinder_bench.reporting.paper`; with
  ``paper=True`` also the paper's cells no run of any kind covers, with the reason),
* the success-rate plot (an SVG bar chart drawn by the page from the table's data, ±std bars),
* the recorded episodes per env (the first recorded episode of each method; videos larger than
  :data:`MAX_VIDEO_BYTES` are listed by path instead of embedded),
* the episodes that ended in an error, and
* the run configuration (runs with their full arguments and commands) and the versions.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime
import html
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from kinder_bench.agents import agent_name
from kinder_bench.evaluation.envs import short_id
from kinder_bench.reporting.paper import (
    METRICS,
    STD_DIGITS,
    Comparison,
    PaperResults,
    Result,
    at_paper_protocol,
    cell_counts,
    fmt_stat,
    load_paper,
    metric_digits,
    variant_name,
)

HTML_FILE = "report.html"
#: Videos above this size are linked by path, not embedded (keeps the page loadable).
MAX_VIDEO_BYTES = 4_000_000
_MIME = {".gif": "image/gif", ".mp4": "video/mp4", ".png": "image/png"}


@dataclasses.dataclass(frozen=True)
class RunDirInfo:
    """What the page shows about one run directory."""

    path: str
    config: Mapping[str, Any]


def _data_uri(path: Path) -> str:
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def _e(x: object) -> str:
    return html.escape(str(x), quote=True)


def _row_data(
    results: Sequence[Result], paper: PaperResults, comparison: Comparison | None
) -> list[dict[str, Any]]:
    rows = []
    for r in results:
        # Only a run at the paper's protocol stands beside the paper's figure.
        conforms = at_paper_protocol(r, paper)
        method = paper.method_of(r.agent) if conforms else None
        row: dict[str, Any] = {
            "env": r.env_id,
            "env_short": short_id(r.env_id),
            "method": r.method,
            "name": r.method if conforms else variant_name(r, paper),
            "agent": r.agent,
            "paper_method": method,
            "seeds": r.num_seeds,
            "episodes": r.episodes,
            "errors": r.errors,
            "sr": r.success.mean,
            "sr_std": r.success.std,
            "command": r.command,
            "reason": None,
        }
        for metric in METRICS:
            stat = r.stat(metric)
            row[metric] = fmt_stat(stat, metric_digits(metric, stat), STD_DIGITS)
            pv = paper.cells.get((r.env_id, method, metric)) if method else None
            row[f"paper_{metric}"] = pv.text() if pv is not None else ""
        rows.append(row)
    if comparison is not None:
        for cell in comparison.paper_cells():
            if cell.reason is None:
                continue
            row = {
                "env": cell.env_id,
                "env_short": short_id(cell.env_id),
                "method": cell.column.agent,
                "name": cell.column.agent,
                "agent": cell.column.agent,
                "paper_method": cell.column.paper_method,
                "seeds": 0,
                "episodes": 0,
                "errors": 0,
                "sr": None,
                "sr_std": None,
                "command": "",
                "reason": cell.reason,
            }
            for metric in METRICS:
                pv = comparison.cell(cell.env_id, cell.column, metric).paper
                row[metric] = "n/r"
                row[f"paper_{metric}"] = pv.text() if pv is not None else ""
            rows.append(row)
    return rows


def _find_video(video: str, run_dirs: Sequence[RunDirInfo]) -> Path | None:
    """A recorded video: where the record says (relative to the directory the run was started
    from), else by its name in a run directory's ``videos/`` (a run directory moved or reported
    from elsewhere)."""
    candidates = [Path(video)] + [Path(d.path) / "videos" / Path(video).name for d in run_dirs]
    return next((p for p in candidates if p.is_file()), None)


def _videos(
    records: Sequence[Mapping[str, Any]], run_dirs: Sequence[RunDirInfo]
) -> dict[tuple[str, str], tuple[Mapping[str, Any], Path]]:
    """(env, method) → the record of its first recorded episode (lowest seed, then episode) and
    the video's path."""
    out: dict[tuple[str, str], tuple[Mapping[str, Any], Path]] = {}
    for r in sorted(records, key=lambda r: (r["seed"], r["episode"])):
        key = (r["env_id"], agent_name(r["label"]))
        if key in out or not r.get("video"):
            continue
        path = _find_video(r["video"], run_dirs)
        if path is not None:
            out[key] = (r, path)
    return out


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d2330;
background:#f6f7f9}
header{background:#1f3a5f;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;opacity:.85;font-size:13px}header code{background:none;color:#fff}
main{padding:16px 24px;max-width:1400px}
section{background:#fff;border:1px solid #dde1e7;border-radius:6px;padding:12px 16px;
margin-bottom:16px}
h2{font-size:16px;margin:0 0 10px}
table{border-collapse:collapse;font-size:13px;width:100%}
th,td{border-bottom:1px solid #e6e8ec;padding:4px 8px;text-align:left;vertical-align:top}
th{background:#f0f2f5;position:sticky;top:0}
td.num{font-variant-numeric:tabular-nums;white-space:nowrap}
td.paper{color:#5a6472;white-space:nowrap}
tr.notrun td{color:#8a94a3;font-style:italic}
.filters{display:flex;gap:24px;flex-wrap:wrap}
.filters fieldset{border:1px solid #dde1e7;border-radius:4px;padding:6px 10px}
.filters label{margin-right:10px;font-size:13px;white-space:nowrap}
.filters button{font-size:12px;margin-left:6px}
.videos{display:flex;flex-wrap:wrap;gap:12px}
figure{margin:0;border:1px solid #e6e8ec;border-radius:4px;padding:6px;background:#fafbfc}
figure img,figure video{max-width:320px;max-height:260px;display:block}
figcaption{font-size:12px;margin-top:4px}
.ok{color:#17803d}.fail{color:#b42318}
code,pre{font-size:12px;background:#f0f2f5;border-radius:3px}
pre{padding:8px;overflow:auto;max-height:320px}
.hidden{display:none !important}
svg text{font-size:11px;fill:#1d2330}
"""

_JS = """
(function(){
  const data = JSON.parse(document.getElementById('report-data').textContent);
  const boxes = sel => Array.from(document.querySelectorAll(sel));
  function chosen(kind){
    return new Set(boxes('input[data-filter="'+kind+'"]').filter(b=>b.checked).map(b=>b.value));
  }
  const COLORS = ['#1f77b4','#ff7f0e','#2ca02c','#d62728','#9467bd','#8c564b','#e377c2',
                  '#7f7f7f','#bcbd22','#17becf'];
  const methods = data.methods;
  function color(m){ return COLORS[methods.indexOf(m) % COLORS.length]; }
  function plot(envs, meths){
    const rows = data.rows.filter(r => r.sr !== null && envs.has(r.env) && meths.has(r.method));
    const envList = data.envs.filter(e => rows.some(r => r.env === e));
    const mList = methods.filter(m => rows.some(r => r.method === m));
    const svg = document.getElementById('plot');
    const ns = 'http://www.w3.org/2000/svg';
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    const groupW = Math.max(60, 26 * mList.length + 20), left = 40, top = 10, h = 180;
    const width = left + groupW * Math.max(1, envList.length) + 10;
    svg.setAttribute('width', width); svg.setAttribute('height', top + h + 60);
    function el(name, attrs, text){
      const e = document.createElementNS(ns, name);
      for (const k in attrs) e.setAttribute(k, attrs[k]);
      if (text !== undefined) e.textContent = text;
      svg.appendChild(e); return e;
    }
    for (const t of [0, 0.25, 0.5, 0.75, 1]){
      const y = top + h * (1 - t);
      el('line', {x1: left, x2: width - 10, y1: y, y2: y, stroke: '#e6e8ec'});
      el('text', {x: 4, y: y + 4}, t.toFixed(2));
    }
    envList.forEach((env, i) => {
      const x0 = left + i * groupW + 10;
      const present = mList.filter(m => rows.some(r => r.env === env && r.method === m));
      present.forEach((m, j) => {
        const r = rows.find(r => r.env === env && r.method === m);
        const bh = h * r.sr, x = x0 + j * 26;
        const bar = el('rect', {x: x, y: top + h - bh, width: 22, height: Math.max(bh, 0.5),
                                fill: color(m)});
        bar.setAttribute('data-method', m);
        const t = document.createElementNS(ns, 'title');
        t.textContent = env + ' / ' + m + ': ' + r.sr.toFixed(2);
        bar.appendChild(t);
        if (r.sr_std !== null){
          const lo = Math.max(0, r.sr - r.sr_std), hi = Math.min(1, r.sr + r.sr_std);
          el('line', {x1: x + 11, x2: x + 11, y1: top + h * (1 - lo), y2: top + h * (1 - hi),
                      stroke: '#1d2330'});
        }
      });
      const label = data.env_short[env] || env;
      el('text', {x: x0, y: top + h + 16}, label);
    });
    const legend = document.getElementById('legend');
    legend.innerHTML = '';
    mList.forEach(m => {
      const s = document.createElement('span');
      s.style.marginRight = '12px';
      s.innerHTML = '<span style="display:inline-block;width:10px;height:10px;background:' +
        color(m) + '"></span> ';
      s.appendChild(document.createTextNode(m));
      legend.appendChild(s);
    });
  }
  function apply(){
    const envs = chosen('env'), meths = chosen('method');
    const notrun = document.getElementById('show-notrun');
    const showNotrun = notrun !== null && notrun.checked;
    boxes('[data-env]').forEach(e => {
      if (e.tagName === 'INPUT') return;
      const okEnv = envs.has(e.getAttribute('data-env'));
      const m = e.getAttribute('data-method');
      const okM = m === null || meths.has(m);
      const okRun = showNotrun || !e.classList.contains('notrun');
      e.classList.toggle('hidden', !(okEnv && okM && okRun));
    });
    const shown = boxes('#results tbody tr').filter(r => !r.classList.contains('hidden')).length;
    document.getElementById('shown').textContent = shown;
    plot(envs, meths);
  }
  boxes('input[data-filter]').forEach(b => b.addEventListener('change', apply));
  const notrunBox = document.getElementById('show-notrun');
  if (notrunBox !== null) notrunBox.addEventListener('change', apply);
  boxes('button[data-all]').forEach(b => b.addEventListener('click', () => {
    const on = b.getAttribute('data-on') === '1';
    boxes('input[data-filter="' + b.getAttribute('data-all') + '"]').forEach(x => x.checked = on);
    apply();
  }));
  apply();
})();
"""


def render_html(
    results: Sequence[Result],
    records: Sequence[Mapping[str, Any]],
    run_dirs: Sequence[RunDirInfo],
    comparison: Comparison | None = None,
    paper: PaperResults | None = None,
    title: str = "KinDERBench report",
    note: str = "",
) -> str:
    """The page as a string (see the module docstring)."""
    paper = paper or load_paper()
    rows = _row_data(results, paper, comparison)
    envs = list(dict.fromkeys(r["env"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    data = {
        "rows": rows,
        "envs": envs,
        "methods": methods,
        "env_short": {e: short_id(e) for e in envs},
    }
    data_json = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    out: list[str] = []
    w = out.append
    w("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>")
    w(
        "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; "
        "img-src data:; media-src data:; style-src 'unsafe-inline'; "
        "script-src 'unsafe-inline'\">"
    )
    w("<link rel='icon' href='data:,'>")
    w("<meta name='viewport' content='width=device-width, initial-scale=1'>")
    w(f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>")
    created = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    w(f"<header><h1>{_e(title)}</h1><p>{len(results)} results from ")
    w(", ".join(f"<code>{_e(d.path)}</code>" for d in run_dirs) or "summaries")
    w(f"; written {created}. {_e(note)}</p></header><main>")

    # Filters.
    w("<section><h2>Filters</h2><div class='filters'>")
    for kind, values, labels in (
        ("env", envs, [short_id(e) for e in envs]),
        ("method", methods, methods),
    ):
        w(f"<fieldset id='filter-{kind}'><legend>{kind}")
        w(f"<button type='button' data-all='{kind}' data-on='1'>all</button>")
        w(f"<button type='button' data-all='{kind}' data-on='0'>none</button></legend>")
        for v, label in zip(values, labels):
            w(
                f"<label><input type='checkbox' data-filter='{kind}' value='{_e(v)}' checked> "
                f"{_e(label)}</label>"
            )
        w("</fieldset>")
    if any(r["reason"] for r in rows):
        w(
            "<fieldset><legend>paper</legend><label><input type='checkbox' id='show-notrun'> "
            "show the paper's cells we did not run (with the reason)</label></fieldset>"
        )
    w("</div></section>")

    # The paper's cells by state (the same counts as the markdown comparison).
    if comparison is not None:
        w("<section><h2>The paper's cells</h2><table id='counts'><tbody>")
        for state, n in cell_counts(comparison):
            w(f"<tr><td>{_e(state)}</td><td class='num'>{n}</td></tr>")
        w("</tbody></table></section>")

    # Table.
    w(f"<section><h2>Results (<span id='shown'>{len(rows)}</span> rows shown)</h2>")
    w(
        "<p style='font-size:12px'>mean ± std over seeds (ours) and the paper's Table II mean ± "
        "its appendix std. SR: success rate; Rwd: return of successful episodes; Inf-Time: "
        "seconds of agent time per episode. The paper's value stands beside ours only for a run at "
        "the paper's protocol (seeds 0–4 × 50 episodes, its step budget, settings and training "
        "budget); other runs are variants named by what differs. n/r: no run of any kind here "
        "(reason given).</p>"
    )
    w("<table id='results'><thead><tr><th>env</th><th>method</th><th>seeds × episodes</th>")
    for metric in METRICS:
        w(f"<th>{_e(metric)}</th><th>paper {_e(metric)}</th>")
    w("<th>errors</th><th>command / reason</th></tr></thead><tbody>")
    for r in rows:
        cls = " class='notrun'" if r["reason"] else ""
        per = f"{r['seeds']} × {r['episodes'] // max(1, r['seeds'])}" if r["seeds"] else ""
        method = r["name"] + (f" ({r['paper_method']})" if r["paper_method"] else "")
        w(
            f"<tr{cls} data-env='{_e(r['env'])}' data-method='{_e(r['method'])}'>"
            f"<td>{_e(r['env_short'])}</td><td>{_e(method)}</td><td class='num'>{per}</td>"
        )
        for metric in METRICS:
            paper_value = _e(r[f"paper_{metric}"])
            w(f"<td class='num'>{_e(r[metric])}</td><td class='paper'>{paper_value}</td>")
        if r["reason"]:
            detail = _e(r["reason"])
        else:
            detail = f"<code>{_e(r['command'])}</code>" if r["command"] else ""
        w(f"<td class='num'>{r['errors'] or ''}</td><td>{detail}</td></tr>")
    w("</tbody></table></section>")

    # Plot.
    w("<section><h2>Success rate</h2><svg id='plot' role='img' aria-label='success rates'>")
    w("</svg><div id='legend' style='font-size:12px'></div></section>")

    # Videos.
    videos = _videos(records, run_dirs)
    if videos:
        w("<section><h2>Episodes</h2>")
        for env in dict.fromkeys(e for e, _ in videos):
            w(f"<div data-env='{_e(env)}'><h3 style='font-size:14px'>{_e(short_id(env))}</h3>")
            w("<div class='videos'>")
            for (e, method), (rec, path) in videos.items():
                if e != env:
                    continue
                status = "success" if rec["success"] else "failure"
                caption = (
                    f"{_e(method)}: <span class='{'ok' if rec['success'] else 'fail'}'>{status}"
                    f"</span> in {rec['steps']} steps (seed {rec['seed']}, episode "
                    f"{rec['episode']})"
                )
                w(f"<figure data-env='{_e(env)}' data-method='{_e(method)}'>")
                if path.stat().st_size > MAX_VIDEO_BYTES:
                    w(f"<p>too large to embed: <code>{_e(path)}</code></p>")
                elif path.suffix.lower() == ".mp4":
                    w(f"<video src='{_data_uri(path)}' controls muted loop></video>")
                else:
                    w(f"<img src='{_data_uri(path)}' alt='{_e(env)} {_e(method)}'>")
                w(f"<figcaption>{caption}</figcaption></figure>")
            w("</div></div>")
        w("</section>")

    # Errors.
    errors = [rec for rec in records if rec.get("error")]
    w(f"<section><h2>Episodes that ended in an error ({len(errors)})</h2>")
    if errors:
        w("<table><thead><tr><th>env</th><th>method</th><th>seed</th><th>episode</th>")
        w("<th>where</th><th>error</th></tr></thead><tbody>")
        for err in errors:
            w(
                f"<tr data-env='{_e(err['env_id'])}' data-method='{_e(agent_name(err['label']))}'>"
                f"<td>{_e(short_id(err['env_id']))}</td><td>{_e(agent_name(err['label']))}</td>"
                f"<td>{err['seed']}</td><td>{err['episode']}</td><td>{_e(err.get('error_in'))}</td>"
                f"<td><code>{_e(err['error'])}</code></td></tr>"
            )
        w("</tbody></table>")
    else:
        w("<p>None.</p>")
    w("</section>")

    # Configuration and versions.
    w("<section><h2>Run configuration and versions</h2>")
    for d in run_dirs:
        cfg = d.config
        w(f"<h3 style='font-size:14px'><code>{_e(d.path)}</code></h3>")
        runs = cfg.get("runs", [])
        if runs:
            w("<table><thead><tr><th>env</th><th>method</th><th>agent</th><th>run id</th>")
            w("<th>seeds</th><th>episodes</th><th>max steps</th><th>arguments</th>")
            w("<th>command</th></tr></thead><tbody>")
            for run in runs:
                args = json.dumps(run.get("agent_args", {}), sort_keys=True)
                label = agent_name(str(run.get("label")))
                w(
                    f"<tr data-env='{_e(run.get('env_id'))}' data-method='{_e(label)}'>"
                    f"<td>{_e(short_id(str(run.get('env_id'))))}</td><td>{_e(label)}"
                    f"</td><td>{_e(run.get('agent'))}</td><td><code>{_e(run.get('run_id'))}"
                    f"</code></td><td>{_e(run.get('seeds'))}</td><td>{_e(run.get('episodes'))}"
                    f"</td><td>{_e(run.get('max_steps'))}</td><td><code>{_e(args)}</code></td>"
                    f"<td><code>{_e(run.get('command', ''))}</code></td></tr>"
                )
            w("</tbody></table>")
        keys = ("versions", "platform", "executable", "imports")
        env_info = {k: cfg[k] for k in keys if k in cfg}
        w(f"<pre>{_e(json.dumps(env_info, indent=2, sort_keys=True))}</pre>")
    w("</section></main>")
    w(f"<script type='application/json' id='report-data'>{data_json}</script>")
    w(f"<script>{_JS}</script></body></html>\n")
    return "".join(out)
