import { describe, expect, it } from 'vitest';
import { applyLive, deriveStatus, fromStatusItem, lastSeenText, type Fleet } from './fleet';

const item = {
  machine_id: 1,
  name: 'Tractor 1',
  online: true,
  position: { type: 'Point', coordinates: [112.3, 32.1] },
  speed_m_s: 2,
  heading_deg: 90,
  job: { id: 7, state: 'running', progress: 0.25 },
  active_alerts: 0,
  alarms: [],
};

describe('fleet status', () => {
  it('reads a /machines/status item', () => {
    const m = fromStatusItem(item);
    expect([m.lon, m.lat, m.job_id, m.progress, m.status]).toEqual([112.3, 32.1, 7, 0.25, 'working']);
  });
  it('offline beats alarm beats working; slow is idle; record flags are not alarms', () => {
    expect(deriveStatus({ machine_id: 1, online: false, active_alerts: 2 })).toBe('offline');
    expect(deriveStatus({ machine_id: 1, online: true, active_alerts: 1, speed_m_s: 2 })).toBe('alarm');
    // a headland turn, implement raised: the record says speed_out_of_range, no alert is open
    expect(deriveStatus({ machine_id: 1, online: true, speed_m_s: 0.6, job_state: 'running', alarms: ['speed_out_of_range'] })).toBe(
      'working',
    );
    expect(deriveStatus({ machine_id: 1, online: false, speed_m_s: 2, job_state: 'running' })).toBe('offline');
    expect(deriveStatus({ machine_id: 1, online: true, speed_m_s: 0.1, job_state: 'running' })).toBe('idle');
    expect(deriveStatus({ machine_id: 1, online: true, speed_m_s: 2 })).toBe('moving');
    expect(deriveStatus({ machine_id: 1, online: true, speed_m_s: 2, implement_down: true })).toBe('working');
  });
});

describe('live messages', () => {
  const start: Fleet = new Map([[1, fromStatusItem(item)]]);
  it('a position moves the machine and keeps its job', () => {
    const f = applyLive(start, { type: 'position', machine_id: 1, lon: 112.31, lat: 32.11, speed_m_s: 2.5, heading_deg: 270 });
    const m = f.get(1)!;
    expect([m.lon, m.lat, m.heading_deg, m.job_id]).toEqual([112.31, 32.11, 270, 7]);
    expect(start.get(1)!.lon).toBe(112.3); // not mutated
  });
  it('a job message updates progress; alerts count up and down', () => {
    let f = applyLive(start, { type: 'job', machine_id: 1, job_id: 7, state: 'running', progress: 0.5 });
    expect(f.get(1)!.progress).toBe(0.5);
    f = applyLive(f, { type: 'alert', machine_id: 1, event: 'started', kind: 'no_data' });
    expect(f.get(1)!.status).toBe('alarm');
    f = applyLive(f, { type: 'alert', machine_id: 1, event: 'ended', kind: 'no_data' });
    expect(f.get(1)!.status).toBe('working');
  });
  it('an offline push turns a red, moving machine grey and drops its speed', () => {
    let f = applyLive(start, { type: 'alert', machine_id: 1, event: 'started', kind: 'rate_error' });
    expect(f.get(1)!.status).toBe('alarm');
    f = applyLive(f, { type: 'machine', event: 'offline', machine_id: 1, online: false });
    const m = f.get(1)!;
    expect([m.status, m.speed_m_s, m.online]).toEqual(['offline', null, false]);
    expect([m.lon, m.lat]).toEqual([112.3, 32.1]); // last known position stays on the map
    f = applyLive(f, { type: 'position', machine_id: 1, lon: 112.3, lat: 32.1, speed_m_s: 2 });
    expect(f.get(1)!.online).toBe(true); // reporting again
  });
  it('a status snapshot replaces the fleet; unknown messages change nothing', () => {
    const f = applyLive(start, { type: 'status', machines: [{ ...item, machine_id: 2, position: null, online: false }] });
    expect([...f.keys()]).toEqual([2]);
    expect(f.get(2)!.status).toBe('offline');
    expect(applyLive(start, { type: 'hello' })).toBe(start);
    expect(applyLive(start, { type: 'position' })).toBe(start);
  });
});

describe('sensor jobs on the fleet view', () => {
  it('keeps the latest NDVI, rate and depth of a position message', () => {
    let f: Fleet = new Map();
    f = applyLive(f, { type: 'position', machine_id: 4, lon: 1, lat: 2, ndvi: 0.45, applied_rate_kg_ha: 277, depth_mm: null });
    expect(f.get(4)?.ndvi).toBe(0.45);
    expect(f.get(4)?.applied_rate_kg_ha).toBe(277);
    f = applyLive(f, { type: 'position', machine_id: 4, lon: 1, lat: 2, depth_mm: 30.5 });
    expect(f.get(4)?.depth_mm).toBe(30.5);
    expect(f.get(4)?.ndvi).toBeNull(); // a record without NDVI: no stale figure
  });
});

describe('last seen', () => {
  const now = Date.UTC(2026, 5, 1, 12, 0, 0);
  it('comes from the server-side silence, not the browser clock', () => {
    const m = fromStatusItem({ machine_id: 3, online: false, silent_s: 300, last_seen_at: '2020-01-01T00:00:00Z' }, now);
    expect(m.last_seen_ms).toBe(now - 300_000);
    expect(m.status).toBe('offline');
    expect(lastSeenText(m.last_seen_ms, now)).toBe('5 min ago');
  });
  it('is now on a position and the sweep time on the offline push', () => {
    const start: Fleet = new Map([[3, fromStatusItem({ machine_id: 3, online: true, silent_s: 1 }, now)]]);
    const f = applyLive(start, { type: 'position', machine_id: 3, lon: 1, lat: 2 }, now + 5000);
    expect(f.get(3)?.last_seen_ms).toBe(now + 5000);
    const off = applyLive(f, { type: 'machine', event: 'offline', machine_id: 3, silent_s: 12 }, now + 20_000);
    expect(off.get(3)?.status).toBe('offline');
    expect(off.get(3)?.last_seen_ms).toBe(now + 8000);
  });
  it('reads as a person would say it', () => {
    expect(lastSeenText(null, now)).toBe('never');
    expect(lastSeenText(now - 2000, now)).toBe('just now');
    expect(lastSeenText(now - 45_000, now)).toBe('45 s ago');
    expect(lastSeenText(now - (3 * 3600 + 5 * 60) * 1000, now)).toBe('3 h 5 min ago');
    expect(lastSeenText(now - 2 * 3600 * 1000, now)).toBe('2 h ago');
  });
});
