// Keys page (admin): list, create (shown once), revoke.
import { $, del, esc, get, post, toast } from "./api.js";
import * as audit from "./audit.js";

export function init() {
  audit.init();
  $("key-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try {
      const k = await post("/keys", { name: $("key-name").value.trim(), role: $("key-role").value });
      $("new-key").textContent = `New ${k.role} key for “${k.name}” (copy it now; it is not shown again): ${k.key}`;
      $("key-name").value = "";
      load();
    } catch (e) { toast(e.message, true); }
  });
}

export function show() { load(); audit.load(false); }

async function load() {
  try {
    const keys = await get("/keys");
    $("key-table").innerHTML = `<tr><th>#</th><th>Name</th><th>Role</th><th>Key starts</th><th>State</th><th></th></tr>` +
      keys.map((k) => `<tr><td>${k.id}</td><td>${esc(k.name)}</td><td>${k.role}</td><td><code>${esc(k.prefix)}…</code></td>
        <td>${k.revoked ? "revoked" : "active"}</td>
        <td>${k.revoked ? "" : `<button class="small danger" data-revoke="${k.id}">Revoke</button>`}</td></tr>`).join("");
    for (const b of document.querySelectorAll("[data-revoke]")) b.onclick = async () => {
      if (!confirm("Revoke this key? Whoever uses it is signed out.")) return;
      try { await del(`/keys/${b.dataset.revoke}`); load(); } catch (e) { toast(e.message, true); }
    };
  } catch (e) { toast(e.message, true); }
}
