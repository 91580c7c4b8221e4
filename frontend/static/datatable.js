// Tables the experimenter can sort (a button in each column header, so the keyboard
// works too) and filter by participant and controller, from the API's JSON tables or
// its CSV downloads.
import { h } from "/static/dom.js";

// RFC 4180: quoted cells may hold commas, quotes ("") and newlines.
export function parseCsv(text) {
  const rows = [];
  let row = [];
  let cell = "";
  let quoted = false;
  for (let i = 0; i < text.length; i++) {
    const ch = text[i];
    if (quoted) {
      if (ch !== '"') cell += ch;
      else if (text[i + 1] === '"') { cell += '"'; i++; }
      else quoted = false;
    } else if (ch === '"') quoted = true;
    else if (ch === ",") { row.push(cell); cell = ""; }
    else if (ch === "\n") { row.push(cell); rows.push(row); row = []; cell = ""; }
    else if (ch !== "\r") cell += ch;
  }
  if (cell !== "" || row.length) { row.push(cell); rows.push(row); }
  const [header = [], ...body] = rows;
  // The CSV writes None and NaN as empty cells.
  return { header, rows: body.map((r) => r.map((v) => (v === "" ? null : v))) };
}

const NUMBER = /^-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/;
// "**7.5**": the paper's bold, the participant's highest score on an instrument.
const BOLD = /^\*\*(.*)\*\*$/;

// A cell's number for sorting, or null.
function numeric(v) {
  if (typeof v === "number") return Number.isFinite(v) ? v : null;
  if (typeof v !== "string") return null;
  const s = v.replace(BOLD, "$1");
  return NUMBER.test(s) ? Number(s) : null;
}

// Long decimals (CSV keeps full precision) shown to 3 places; integers and text as they are.
export function cellText(v) {
  if (v == null) return "–";
  if (typeof v === "boolean") return v ? "yes" : "no";
  if (v === "true" || v === "false") return v === "true" ? "yes" : "no";
  const n = numeric(v);
  const s = String(v);
  if (n != null && !Number.isInteger(n) && (s.split(".")[1] || "").length > 3) return n.toFixed(3);
  return s;
}

export function cellNode(v) {
  const m = typeof v === "string" ? v.match(BOLD) : null;
  if (m) return h("strong", { class: "highest", title: "highest score of this participant on this instrument" }, m[1]);
  return cellText(v);
}

function compare(a, b) {
  if (a == null || b == null) return a == null ? (b == null ? 0 : 1) : -1;
  const na = numeric(a);
  const nb = numeric(b);
  if (na != null && nb != null) return na - nb;
  if (na != null) return -1;
  if (nb != null) return 1;
  return String(a).localeCompare(String(b), undefined, { numeric: true });
}

// Rows sorted by `sort` ({col, dir: 1 | -1}); nulls stay last either way.
export function sortRows(rows, sort) {
  if (!sort) return rows;
  const idx = rows.map((r, i) => i);
  idx.sort((i, j) => {
    const a = rows[i][sort.col];
    const b = rows[j][sort.col];
    if (a == null || b == null) return compare(a, b) || i - j;
    return sort.dir * compare(a, b) || i - j;
  });
  return idx.map((i) => rows[i]);
}

/**
 * A sortable table element.
 * - `header`: column names; `rows`: arrays of cells (raw values).
 * - `sort`: the current {col, dir} or null; `onSort(newSort)` is called on a header press.
 * - `render(row, col)`: optional cell content (a node or text) instead of the value.
 * - `rowAttrs(row)`: optional attributes of each <tr>.
 * - `sortable(col)`: optional, false for columns without a meaningful order.
 */
export function sortableTable({ header, rows, sort = null, onSort, render = null, rowAttrs = null,
  sortable = () => true, cls = "list" }) {
  const shown = sortRows(rows, sort);
  return h("table", { class: cls },
    h("thead", {}, h("tr", {}, header.map((name, col) => {
      if (!sortable(col)) return h("th", {}, name);
      const active = sort && sort.col === col;
      const dir = active ? sort.dir : 0;
      return h("th", { "aria-sort": dir === 1 ? "ascending" : dir === -1 ? "descending" : "none" },
        h("button", {
          type: "button", class: "sort", "data-col": col,
          title: `sort by ${name}`,
          onclick: () => onSort({ col, dir: active ? -sort.dir : 1 }),
        }, name, h("span", { class: "sort-mark", "aria-hidden": "true" }, dir === 1 ? " ▲" : dir === -1 ? " ▼" : "")));
    }))),
    h("tbody", {}, shown.map((r) => h("tr", rowAttrs ? rowAttrs(r) : {},
      r.map((v, col) => h("td", {}, render ? render(r, col) : cellNode(v)))))));
}
