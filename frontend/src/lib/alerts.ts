/**
 * Alert groups (GET /alerts/groups): every alert of one kind on one job (or, without a
 * job, on one machine) is one line with a count, acknowledged together (POST /alerts/ack).
 * A job whose rate wandered in and out of tolerance 16 times is one line, not 16.
 */
import type { Schemas } from '../api/client';

/** The server's alert group: these helpers need its counts and key, the rest may follow. */
export type AlertGroup = Pick<
  Schemas['AlertGroup'],
  'machine_id' | 'job_id' | 'kind' | 'count' | 'active' | 'unacknowledged'
> &
  Partial<Schemas['AlertGroup']>;

export function groupKey(g: Pick<AlertGroup, 'machine_id' | 'job_id' | 'kind'>): string {
  return `${g.machine_id}:${g.job_id ?? '-'}:${g.kind}`;
}

/** Groups someone still has to look at (the "Alerts N" badge). */
export function openGroupCount(groups: AlertGroup[]): number {
  return groups.filter((g) => g.unacknowledged > 0).length;
}

/** The body of POST /alerts/ack for a group. */
export function ackBody(g: AlertGroup): Schemas['AckGroupIn'] {
  return { machine_id: g.machine_id, job_id: g.job_id ?? null, kind: g.kind };
}

/** After "acknowledge all": the group is acknowledged, the others unchanged (new array). */
export function markAcknowledged(groups: AlertGroup[], key: string): AlertGroup[] {
  return groups.map((g) => (groupKey(g) === key ? { ...g, unacknowledged: 0, acknowledged: true } : g));
}

/** "rate error ×16 · 2 active" */
export function groupLabel(g: AlertGroup): string {
  const kind = g.kind.replace(/_/g, ' ');
  const times = g.count > 1 ? ` ×${g.count}` : '';
  const active = g.active > 0 ? ` · ${g.active} active` : '';
  return `${kind}${times}${active}`;
}
