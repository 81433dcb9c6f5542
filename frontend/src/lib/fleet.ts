/**
 * Fleet state from GET /machines/status and the /live WebSocket messages
 * ("status" snapshot, "position", "job", "alert", "machine" offline), as a pure reducer so the
 * rules (what counts as working, idle, alarm, offline) are unit-tested.
 */

export interface FleetMachine {
  machine_id: number;
  name?: string;
  online?: boolean;
  lon?: number | null;
  lat?: number | null;
  heading_deg?: number | null;
  speed_m_s?: number | null;
  job_id?: number | null;
  job_state?: string | null;
  progress?: number | null; // 0..1
  implement_down?: boolean;
  active_alerts?: number;
  alarms?: string[];
  t?: number | string | null;
  /** when the server last heard from the machine, in this browser's clock (ms since epoch) */
  last_seen_ms?: number | null;
  /** sensor jobs: latest filtered NDVI and applied rate (seed 000), depth (seed 002) */
  ndvi?: number | null;
  applied_rate_kg_ha?: number | null;
  depth_mm?: number | null;
  status: 'working' | 'moving' | 'idle' | 'alarm' | 'offline';
}

export type Fleet = Map<number, FleetMachine>;

const MOVING_M_S = 0.3;

function num(v: unknown): number | null {
  return typeof v === 'number' && Number.isFinite(v) ? v : null;
}

/**
 * The present, not the last record: offline beats everything (a silent machine's flags are
 * history), then an active alert; a record's own alarm flags (a slow headland turn with the
 * implement raised) are not an alarm. Then working (implement down or job running while
 * moving), moving, idle.
 */
export function deriveStatus(m: Omit<FleetMachine, 'status'>): FleetMachine['status'] {
  if (m.online === false) return 'offline';
  if ((m.active_alerts ?? 0) > 0) return 'alarm';
  const moving = (m.speed_m_s ?? 0) > MOVING_M_S;
  if (moving && (m.implement_down || m.job_state === 'running')) return 'working';
  if (moving) return 'moving';
  return 'idle';
}

/** One item of GET /machines/status (position as a GeoJSON Point, job as an object). */
export function fromStatusItem(o: Record<string, unknown>, now = Date.now()): FleetMachine {
  const pos = o.position as { coordinates?: number[] } | null | undefined;
  const job = o.job as Record<string, unknown> | null | undefined;
  const m: Omit<FleetMachine, 'status'> = {
    machine_id: Number(o.machine_id ?? o.id),
    name: typeof o.name === 'string' ? o.name : undefined,
    online: typeof o.online === 'boolean' ? o.online : undefined,
    lon: pos?.coordinates ? pos.coordinates[0] : num(o.lon),
    lat: pos?.coordinates ? pos.coordinates[1] : num(o.lat),
    heading_deg: num(o.heading_deg),
    speed_m_s: num(o.speed_m_s) ?? num(o.speed_filtered_m_s),
    job_id: job ? Number(job.id) : num(o.job_id),
    job_state: job ? (job.state as string) : null,
    progress: job ? num(job.progress) : num(o.progress),
    active_alerts: num(o.active_alerts) ?? 0,
    alarms: Array.isArray(o.alarms) ? (o.alarms as string[]) : [],
    t: (o.last_t as string) ?? null,
    last_seen_ms: seenAt(o.silent_s, now),
  };
  return { ...m, status: deriveStatus(m) };
}

export interface LiveMsg {
  type?: string;
  [k: string]: unknown;
}

/** Applies one live message; returns the same map when nothing changed (cheap React updates). */
export function applyLive(fleet: Fleet, msg: LiveMsg, now = Date.now()): Fleet {
  if (msg.type === 'status' && Array.isArray(msg.machines)) {
    const next: Fleet = new Map();
    for (const o of msg.machines as Record<string, unknown>[]) {
      const m = fromStatusItem(o, now);
      next.set(m.machine_id, { ...fleet.get(m.machine_id), ...m });
    }
    return next;
  }
  const id = Number(msg.machine_id);
  if (!Number.isFinite(id)) return fleet;
  const prev: Omit<FleetMachine, 'status'> = fleet.get(id) ?? { machine_id: id };
  let upd: Omit<FleetMachine, 'status'>;
  if (msg.type === 'position') {
    upd = {
      ...prev,
      online: true,
      lon: num(msg.lon) ?? prev.lon,
      lat: num(msg.lat) ?? prev.lat,
      heading_deg: num(msg.heading_deg) ?? prev.heading_deg,
      speed_m_s: num(msg.speed_m_s) ?? num(msg.speed_filtered_m_s) ?? prev.speed_m_s,
      job_id: num(msg.job_id) ?? prev.job_id,
      implement_down: typeof msg.implement_down === 'boolean' ? msg.implement_down : prev.implement_down,
      alarms: Array.isArray(msg.alarms) ? (msg.alarms as string[]) : prev.alarms,
      t: (msg.t as number) ?? prev.t,
      last_seen_ms: now,
      ndvi: num(msg.ndvi),
      applied_rate_kg_ha: num(msg.applied_rate_kg_ha),
      depth_mm: num(msg.depth_mm),
    };
  } else if (msg.type === 'job') {
    upd = {
      ...prev,
      job_id: num(msg.job_id) ?? prev.job_id,
      job_state: (msg.state as string) ?? prev.job_state,
      progress: num(msg.progress) ?? prev.progress,
    };
  } else if (msg.type === 'machine' && msg.event === 'offline') {
    // pushed by the server after the heartbeat timeout: no speed, no flags any more
    upd = { ...prev, online: false, speed_m_s: null, alarms: [], last_seen_ms: seenAt(msg.silent_s, now) ?? prev.last_seen_ms };
  } else if (msg.type === 'alert') {
    const delta = msg.event === 'ended' ? -1 : msg.event === 'started' || msg.event == null ? 1 : 0;
    upd = { ...prev, active_alerts: Math.max(0, (prev.active_alerts ?? 0) + delta) };
  } else return fleet;
  const next = new Map(fleet);
  next.set(id, { ...upd, status: deriveStatus(upd) });
  return next;
}

/**
 * When the server last heard from a machine, from its ``silent_s`` (seconds, the server's
 * own now minus last_seen_at): the browser's clock may be off by minutes, a difference of
 * two server times is not.
 */
function seenAt(silent: unknown, now: number): number | null {
  const s = num(silent);
  return s == null ? null : now - s * 1000;
}

/** "just now", "45 s ago", "12 min ago", "3 h 5 min ago", then the date and time. */
export function lastSeenText(seenMs: number | null | undefined, now = Date.now()): string {
  if (seenMs == null) return 'never';
  const s = Math.max(0, Math.round((now - seenMs) / 1000));
  if (s < 5) return 'just now';
  if (s < 60) return `${s} s ago`;
  const min = Math.floor(s / 60);
  if (min < 60) return `${min} min ago`;
  const h = Math.floor(min / 60);
  if (h < 24) return min % 60 ? `${h} h ${min % 60} min ago` : `${h} h ago`;
  return new Date(seenMs).toLocaleString();
}
