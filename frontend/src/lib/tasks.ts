/**
 * Background tasks (GET /api/v1/tasks/{id}): recognising a 202 answer, polling a task until
 * it ends, and the text a progress bar shows. Pure functions (the fetch and the wait are
 * passed in) so they are tested without a browser.
 */

import type { components } from '../api/generated/schema';

type TaskOut = components['schemas']['TaskOut'];
export type TaskStatus = TaskOut['status'];

/** What the UI reads of a task (the server's ``TaskOut``, generated). */
export type TaskView = Pick<TaskOut, 'id' | 'kind' | 'status' | 'progress' | 'message' | 'result' | 'result_url' | 'error' | 'url'> &
  Partial<Pick<TaskOut, 'cancel_requested' | 'counts'>> & { items?: TaskView[] | null };

const FINAL: readonly TaskStatus[] = ['succeeded', 'failed', 'cancelled'];

export function isFinal(t: Pick<TaskView, 'status'>): boolean {
  return FINAL.includes(t.status);
}

/** A 202 answer of a background request is a task: it has a tasks URL and a status. */
export function isTask(body: unknown): body is TaskView {
  if (!body || typeof body !== 'object') return false;
  const b = body as Record<string, unknown>;
  return typeof b.url === 'string' && b.url.includes('/tasks/') && typeof b.status === 'string';
}

/** "42 % · storing 75,000 cells"; a batch says how many of its tasks are done. */
export function progressLabel(t: TaskView): string {
  const pct = `${Math.floor(Math.min(Math.max(t.progress, 0), 1) * 100)} %`;
  if (t.status === 'failed') return `Failed: ${t.error ?? 'unknown error'}`;
  if (t.status === 'cancelled') return 'Cancelled';
  if (t.status === 'succeeded') return 'Done';
  if (t.status === 'queued') return 'Waiting for a worker…';
  return t.message ? `${pct} · ${t.message}` : pct;
}

export interface PollOptions {
  /** Called with every view read, the last one included. */
  onUpdate?: (t: TaskView) => void;
  intervalMs?: number;
  /** Stops polling (the promise then resolves with the last view read). */
  signal?: { aborted: boolean };
  sleep?: (ms: number) => Promise<void>;
}

const realSleep = (ms: number) => new Promise<void>((resolve) => setTimeout(resolve, ms));

/**
 * Read the task until it ends. Waits grow from ``intervalMs`` to 4x it while nothing
 * changes (a long plan does not hammer the server) and drop back on every change.
 */
export async function pollTask(
  get: (url: string) => Promise<TaskView>,
  url: string,
  opts: PollOptions = {},
): Promise<TaskView> {
  const base = opts.intervalMs ?? 500;
  const sleep = opts.sleep ?? realSleep;
  let wait = base;
  let last: TaskView | null = null;
  for (;;) {
    const t = await get(url);
    opts.onUpdate?.(t);
    if (isFinal(t) || opts.signal?.aborted) return t;
    const changed = !last || t.progress !== last.progress || t.status !== last.status;
    wait = changed ? base : Math.min(wait * 2, base * 4);
    last = t;
    await sleep(wait);
    if (opts.signal?.aborted) return t;
  }
}
