import { describe, expect, it, vi } from 'vitest';

// client.ts builds its base URL from the page's location at import (none under node)
vi.hoisted(() => {
  (globalThis as { location?: unknown }).location ??= { origin: 'http://127.0.0.1', protocol: 'http:', host: '127.0.0.1' };
});

import { QueryClient } from '@tanstack/react-query';
import { ApiError } from './client';
import { invalidateAll, makeQueryClient, qk } from './hooks';

const seed = (qc: QueryClient, keys: readonly (readonly unknown[])[]) => keys.forEach((k) => qc.setQueryData(k, { seeded: true }));
const stale = (qc: QueryClient, k: readonly unknown[]) => qc.getQueryState(k)?.isInvalidated ?? false;

describe('query keys', () => {
  it('a field edit refetches that field, its plans and soil, and every field list, nothing else', async () => {
    const qc = new QueryClient();
    const keys = [
      qk.field(7),
      qk.fieldPlans(7),
      qk.soilSamples(7),
      qk.imagery(7),
      qk.fields({ q: 'north' }),
      qk.fields({ limit: 500 }),
      qk.field(8),
      qk.plan(7),
      qk.imagery(),
    ];
    seed(qc, keys);
    await invalidateAll(qc, [qk.field(7), qk.fields()]);
    expect(keys.map((k) => stale(qc, k))).toEqual([true, true, true, true, true, true, false, false, false]);
  });

  it('a prescription edit refetches the prescription and the plan list of it, not stored versions elsewhere', async () => {
    const qc = new QueryClient();
    seed(qc, [qk.prescription(3), qk.prescriptionVersion(3, 1), qk.prescription(4), qk.planPrescriptions(9)]);
    await invalidateAll(qc, [qk.prescription(3), qk.planPrescriptions(9)]);
    expect(stale(qc, qk.prescription(3))).toBe(true);
    expect(stale(qc, qk.planPrescriptions(9))).toBe(true);
    expect(stale(qc, qk.prescription(4))).toBe(false);
  });

  it('list and detail keys never collide (machines list vs machine 0 / status)', () => {
    expect(qk.machines()).not.toEqual(qk.machine(0));
    expect(qk.machineStatus()).not.toEqual(qk.machines());
    expect(qk.jobs()).toEqual(['jobs', 'list']);
    expect(qk.jobs({ limit: 5 }).slice(0, 2)).toEqual(qk.jobs());
  });
});

describe('the app cache', () => {
  it('does not retry answers a retry cannot change (4xx), retries a server error once', () => {
    const retry = makeQueryClient().getDefaultOptions().queries!.retry as (n: number, e: unknown) => boolean;
    const err = (status: number) => new ApiError(status, { message: 'x', items: [] } as never);
    expect(retry(0, err(404))).toBe(false);
    expect(retry(0, err(422))).toBe(false);
    expect(retry(0, err(503))).toBe(true);
    expect(retry(1, err(503))).toBe(false);
    expect(retry(0, new TypeError('Failed to fetch'))).toBe(true);
  });
});
