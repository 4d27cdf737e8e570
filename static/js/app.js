// Console shell: sign in with a key, tabs, and the pages (each module exports init/show).
import { $, forgetKey, get, savedKey, storeKey, toast } from "./api.js";
import * as live from "./live.js";
import * as tuning from "./tuning.js";
import * as audio from "./audio.js";
import * as workbench from "./workbench.js";
import * as friction from "./friction.js";
import * as practice from "./practice.js";
import * as keys from "./keys.js";

const pages = { live, tuning, audio, workbench, friction, practice, keys };
const started = new Set();
const ROLE_RANK = { viewer: 1, operator: 2, engineer: 3, admin: 4 };
export const session = { name: "", role: "viewer", can: (r) => ROLE_RANK[session.role] >= ROLE_RANK[r] };
window.console3dat = { session, pages };

function showTab(name) {
  for (const b of document.querySelectorAll("#tabs button")) b.classList.toggle("active", b.dataset.tab === name);
  for (const p of document.querySelectorAll(".page")) p.hidden = p.id !== `page-${name}`;
  const page = pages[name];
  if (!started.has(name)) { started.add(name); page.init?.(session); }
  page.show?.();
  history.replaceState(null, "", `#${name}`);
}

async function signIn(key, remember) {
  storeKey(key, remember);
  const me = await get("/whoami");
  session.name = me.name;
  session.role = me.role;
  $("who").textContent = `${me.name} · ${me.role}`;
  $("signin").hidden = true;
  $("main").hidden = false;
  $("tabs").hidden = false;
  $("session").hidden = false;
  document.body.dataset.role = me.role;
  for (const b of document.querySelectorAll("#tabs button[data-role]")) b.hidden = !session.can(b.dataset.role);
  if (!started.has("live")) { started.add("live"); live.init(session); }  // telemetry runs on every page
  const wanted = location.hash.slice(1);
  showTab(pages[wanted] && !document.querySelector(`#tabs button[data-tab=${wanted}]`)?.hidden ? wanted : "live");
}

function signOut(message) {
  forgetKey();
  location.hash = "";
  location.reload();
  if (message) toast(message, true);
}

document.addEventListener("DOMContentLoaded", () => {
  for (const b of document.querySelectorAll("#tabs button")) b.addEventListener("click", () => showTab(b.dataset.tab));
  $("signout").addEventListener("click", () => signOut());
  $("signin-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    $("signin-error").textContent = "";
    try {
      await signIn($("key-input").value.trim(), $("remember").checked);
    } catch (err) {
      forgetKey();
      $("signin-error").textContent = err.status === 401 ? "That key is not known (or was revoked)." : err.message;
    }
  });
  window.addEventListener("auth-lost", () => {
    if (!$("main").hidden) signOut("Your key is no longer accepted; sign in again.");
  });
  const key = savedKey();
  if (key) signIn(key, false).catch(() => { forgetKey(); });
});
