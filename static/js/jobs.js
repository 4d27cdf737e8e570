// A job card: follow a job's progress into its bar and status line, cancel it, hand over its result.
// The card's elements share a prefix: PREFIX-bar, PREFIX-status, PREFIX-cancel, PREFIX-error.
import { $, get, post } from "./api.js";

export function jobCard(prefix, onDone, onCancelError = (msg) => { $(`${prefix}-error`).textContent = msg; }) {
  let jobId = null;
  let timer = null;

  async function poll() {
    try {
      const j = await get(`/jobs/${jobId}`);
      $(`${prefix}-bar`).style.width = `${(100 * j.progress).toFixed(0)}%`;
      $(`${prefix}-status`).textContent = `Job ${j.id}: ${j.state} · ${(100 * j.progress).toFixed(0)} %${j.message && j.message !== j.state ? ` · ${j.message}` : ""}`;
      if (["done", "failed", "cancelled"].includes(j.state)) {
        clearInterval(timer);
        $(`${prefix}-cancel`).disabled = true;
        if (j.state === "done") onDone(j.result);
        if (j.state === "failed") $(`${prefix}-error`).textContent = j.message;
      }
    } catch (e) { clearInterval(timer); $(`${prefix}-error`).textContent = e.message; }
  }

  $(`${prefix}-cancel`).addEventListener("click", async () => {
    if (jobId) try { await post(`/jobs/${jobId}/cancel`); } catch (e) { onCancelError(e.message); }
  });

  return {
    follow(id) {
      jobId = id;
      $(`${prefix}-cancel`).disabled = false;
      clearInterval(timer);
      timer = setInterval(poll, 300);
      poll();
    },
  };
}
