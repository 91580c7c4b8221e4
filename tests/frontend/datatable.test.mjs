// The results tables' pure parts: CSV parsing, cell text, sorting.
import assert from "node:assert/strict";
import { test } from "node:test";
import { cellText, parseCsv, sortRows } from "/static/datatable.js";

test("CSV: quoted commas, doubled quotes and newlines; empty cells are null", () => {
  const { header, rows } = parseCsv('a,b,c\r\n"x, y","say ""hi""",\n"two\nlines",1.5,7\n');
  assert.deepEqual(header, ["a", "b", "c"]);
  assert.deepEqual(rows, [["x, y", 'say "hi"', null], ["two\nlines", "1.5", "7"]]);
});

test("cells: long decimals to 3 places, integers and text as given, booleans in words", () => {
  assert.equal(cellText("0.123456"), "0.123");
  assert.equal(cellText("0.12"), "0.12");
  assert.equal(cellText("12"), "12");
  assert.equal(cellText(null), "–");
  assert.equal(cellText("true"), "yes");
  assert.equal(cellText("E-UMC"), "E-UMC");
});

test("sorting: numbers as numbers, nulls last either way", () => {
  const rows = [["b", "10"], ["a", "9"], ["c", null], ["d", "**11**"]];
  assert.deepEqual(sortRows(rows, { col: 1, dir: 1 }).map((r) => r[0]), ["a", "b", "d", "c"]);
  assert.deepEqual(sortRows(rows, { col: 1, dir: -1 }).map((r) => r[0]), ["d", "b", "a", "c"]);
  assert.equal(sortRows(rows, null), rows);
});
