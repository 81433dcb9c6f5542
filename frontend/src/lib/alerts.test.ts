import { describe, expect, it } from 'vitest';
import { ackBody, groupKey, groupLabel, markAcknowledged, openGroupCount, type AlertGroup } from './alerts';

const g = (over: Partial<AlertGroup>): AlertGroup => ({
  machine_id: 1,
  job_id: 7,
  kind: 'rate_error',
  count: 16,
  active: 1,
  unacknowledged: 16,
  ...over,
});

describe('alert groups', () => {
  it('one job raising 16 rate alerts is one line, counted once in the badge', () => {
    const groups = [g({}), g({ kind: 'cells_not_applied', count: 1, active: 0, unacknowledged: 1 }), g({ job_id: 8, unacknowledged: 0 })];
    expect(openGroupCount(groups)).toBe(2);
    expect(groupLabel(groups[0])).toBe('rate error ×16 · 1 active');
    expect(groupLabel(groups[1])).toBe('cells not applied');
  });
  it('acknowledge all: posts the group and marks only that group', () => {
    const groups = [g({}), g({ kind: 'fix_lost', unacknowledged: 2 })];
    expect(ackBody(groups[0])).toEqual({ machine_id: 1, job_id: 7, kind: 'rate_error' });
    const after = markAcknowledged(groups, groupKey(groups[0]));
    expect(after.map((x) => x.unacknowledged)).toEqual([0, 2]);
    expect(openGroupCount(after)).toBe(1);
    expect(groups[0].unacknowledged).toBe(16); // not mutated
    expect(groupKey(g({ job_id: null }))).toBe('1:-:rate_error');
  });
});
