// Background jobs (model fitting, utilities): poll until done, reporting progress.
import * as api from "/static/api_client.js";

export async function waitForJob(jobId, onProgress, intervalMs = 300) {
  for (;;) {
    const job = await api.models.getJob(jobId);
    onProgress(job);
    if (job.status === "done") return job;
    if (job.status === "failed" || job.status === "cancelled") {
      throw new Error(job.message || `job ${job.status}`);
    }
    await new Promise((r) => setTimeout(r, intervalMs));
  }
}

// A <progress> bar with a caption, bound to a job.
export function progressView(bar, caption) {
  return (job) => {
    bar.value = job.progress;
    bar.dataset.status = job.status;
    caption.textContent = `${job.status} · ${(job.progress * 100).toFixed(0)} %` +
      (job.message ? ` · ${job.message}` : "");
  };
}
