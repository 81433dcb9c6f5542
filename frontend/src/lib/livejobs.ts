/**
 * A job list kept current between polls: the live feed's `job` messages (state and progress
 * as the server moved them) are laid over the last answer of GET /jobs until a newer answer
 * arrives. Without this a list polled every few seconds showed "running 2.8 %" for a job
 * the server had completed.
 */

export interface JobLive {
  state?: string;
  progress?: number;
  /** when the message arrived (ms since epoch, this browser's clock) */
  at: number;
}

/** The live part of one `job` message, or null if it is not one. */
export function jobLive(msg: Record<string, unknown>, now = Date.now()): [number, JobLive] | null {
  if (msg.type !== 'job' || typeof msg.job_id !== 'number') return null;
  return [
    msg.job_id,
    {
      state: typeof msg.state === 'string' ? msg.state : undefined,
      progress: typeof msg.progress === 'number' && Number.isFinite(msg.progress) ? msg.progress : undefined,
      at: now,
    },
  ];
}

/** `jobs` with what the feed said since they were fetched (`fetchedAt`, ms); older news is dropped. */
export function withLive<T extends { id: number; state: string; progress?: number | null }>(
  jobs: readonly T[],
  live: ReadonlyMap<number, JobLive>,
  fetchedAt: number,
): T[] {
  return jobs.map((j) => {
    const l = live.get(j.id);
    if (!l || l.at <= fetchedAt) return j;
    return { ...j, state: l.state ?? j.state, progress: l.progress ?? j.progress };
  });
}
