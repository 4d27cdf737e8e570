// Audit log panel (admin, on the Keys page): who changed what, newest first, a page at a time.
import { $, esc, get, toast } from "./api.js";

const PAGE = 50;
let before = null; // the next page's before_id, or null at the end

export function init() {
  $("audit-refresh").addEventListener("click", () => load(false));
  $("audit-more").addEventListener("click", () => load(true));
}

export async function load(more) {
  try {
    const q = more && before ? `?limit=${PAGE}&before_id=${before}` : `?limit=${PAGE}`;
    const page = await get(`/audit${q}`);
    const rows = page.entries.map((e) => `<tr><td>${new Date(e.t_s * 1000).toLocaleString()}</td>
      <td>${esc(e.key_name)} <span class="muted">#${e.key_id}</span></td><td>${esc(e.role)}</td>
      <td><code>${esc(e.action)}</code></td><td>${esc(e.target)}</td>
      <td><code>${esc(Object.keys(e.detail).length ? JSON.stringify(e.detail) : "")}</code></td></tr>`).join("");
    const head = `<tr><th>When</th><th>Key</th><th>Role</th><th>Action</th><th>Target</th><th>Detail</th></tr>`;
    if (more) $("audit-table").insertAdjacentHTML("beforeend", rows);
    else $("audit-table").innerHTML = head + (rows || `<tr><td colspan="6" class="muted">no entries yet</td></tr>`);
    before = page.next_before_id;
    $("audit-more").hidden = before === null;
  } catch (e) { toast(e.message, true); }
}
