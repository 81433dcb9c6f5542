import { useEffect, useRef, useState } from 'react';
import { call, client } from '../api/client';
import { qk, useAlertGroups, useApiMutation, useInvalidate, useMachineStatus } from '../api/hooks';
import { FleetMap } from '../components/FleetMap';
import { LastSeen } from '../components/LastSeen';
import { ErrorBox } from '../components/Status';
import { statusColor } from '../lib/colors';
import { applyLive, fromStatusItem, type Fleet, type FleetMachine } from '../lib/fleet';
import { addTrailPoint, type TrailPoint } from '../lib/trail';
import { compass, formatPercent, formatRate, formatSpeed } from '../lib/units';
import { useLive } from '../live';
import { ackBody, groupKey, groupLabel, markAcknowledged, openGroupCount, type AlertGroup } from '../lib/alerts';

const TRAIL = 300;

/** Live fleet: positions over WebSocket, status colours, labels, last seen, job progress and coverage, alerts. */
export function FleetScreen() {
  // Status seeds the map once (the query is cached); the live stream moves it on from there.
  const status = useMachineStatus();
  const alerts = useAlertGroups({ limit: 50 }, { refetchInterval: 15_000 });
  const refresh = useInvalidate();
  const [fleet, setFleet] = useState<Fleet>(new Map());
  const [acked, setAcked] = useState<AlertGroup[] | null>(null);
  // the machine the map follows (picked in the list); null: the map stays where it is put
  const [followed, setFollowed] = useState<number | null>(null);
  const trails = useRef(new Map<number, TrailPoint[]>());

  useEffect(() => {
    if (status.data) setFleet(new Map(status.data.items.map((o) => [o.machine_id, fromStatusItem(o)])));
  }, [status.data]);
  // an acknowledgement shows at once; the next answer of the alerts query replaces it
  useEffect(() => setAcked(null), [alerts.data]);
  const groups = acked ?? alerts.data?.items ?? [];

  const live = useLive((msg) => {
    if (msg.type === 'alert') void refresh(qk.alertGroups());
    if (msg.type === 'position' && typeof msg.lon === 'number' && typeof msg.lat === 'number') {
      const id = Number(msg.machine_id);
      const tr = trails.current.get(id) ?? [];
      const t = typeof msg.t === 'number' ? msg.t : Date.now() / 1000;
      addTrailPoint(tr, { lon: msg.lon, lat: msg.lat, t }, TRAIL);
      trails.current.set(id, tr);
    }
    setFleet((cur) => applyLive(cur, msg));
  });

  const ack = useApiMutation((g: AlertGroup) => call(client.POST('/api/v1/alerts/ack', { body: ackBody(g) })), {
    invalidate: () => [qk.alertGroups()],
  });
  const ackAll = async (g: AlertGroup) => {
    setAcked(markAcknowledged(groups, groupKey(g)));
    await ack.mutateAsync(g).catch(() => setAcked(null));
  };
  const error = status.error ?? alerts.error ?? ack.error;
  return (
    <div className="split">
      <aside className="panel" aria-label="Fleet">
        <h2>Fleet</h2>
        <p className="muted">
          Live: <span data-testid="live-state">{live}</span>
        </p>
        <ErrorBox error={error} />
        <div className="row wrap small" data-testid="fleet-legend">
          {(['working', 'moving', 'idle', 'alarm', 'offline'] as const).map((st) => (
            <span key={st}>
              <span className="dot" style={{ background: statusColor(st) }} />
              {st}
            </span>
          ))}
        </div>
        <ul className="list" data-testid="fleet-list">
          {[...fleet.values()]
            .sort((a, b) => a.machine_id - b.machine_id)
            .map((m) => (
              <MachineItem
                key={m.machine_id}
                m={m}
                followed={followed === m.machine_id}
                onFollow={() => setFollowed((f) => (f === m.machine_id ? null : m.machine_id))}
              />
            ))}
        </ul>
        <Alerts groups={groups} fleet={fleet} onAck={(g) => void ackAll(g)} />
      </aside>
      <FleetMap fleet={fleet} trails={trails.current} follow={followed} />
    </div>
  );
}

function MachineItem({ m, followed, onFollow }: { m: FleetMachine; followed: boolean; onFollow: () => void }) {
  const cls = [m.status === 'offline' ? 'machine-offline' : '', followed ? 'followed' : ''].filter(Boolean).join(' ');
  return (
    <li data-testid={`fleet-machine-${m.machine_id}`} className={cls || undefined}>
      <span className="dot" style={{ background: statusColor(m.status) }} />
      <a href={`#/machines/${m.machine_id}`}>{m.name ?? `Machine #${m.machine_id}`}</a>{' '}
      <span className="muted" data-testid={`machine-status-${m.machine_id}`}>
        {m.status}
      </span>
      <div>
        <LastSeen seenMs={m.last_seen_ms} online={m.online} testid={`machine-last-seen-${m.machine_id}`} />
      </div>
      <div className="muted small">
        {formatSpeed(m.speed_m_s)} · heading {m.heading_deg != null ? `${Math.round(m.heading_deg)}° ${compass(m.heading_deg)}` : '–'}
        {m.job_id != null && (
          <>
            {' '}
            · <a href={`#/jobs/${m.job_id}`}>job #{m.job_id}</a> {m.job_state ?? ''}{' '}
            <span data-testid={`machine-progress-${m.machine_id}`}>{m.progress != null ? formatPercent(m.progress) : ''}</span>
          </>
        )}
      </div>
      {m.progress != null && (
        <progress
          max={1}
          value={m.progress}
          style={{ width: '100%' }}
          aria-label={`job progress of ${m.name ?? m.machine_id}`}
          data-testid={`machine-progressbar-${m.machine_id}`}
        />
      )}
      {(m.ndvi != null || m.depth_mm != null) && (
        <div className="small" data-testid={`machine-sensor-${m.machine_id}`}>
          {m.ndvi != null && `NDVI ${m.ndvi.toFixed(2)} · ${formatRate(m.applied_rate_kg_ha, 0)}`}
          {m.depth_mm != null && `depth ${m.depth_mm.toFixed(1)} mm`}
        </div>
      )}
      <div className="muted small" data-testid={`machine-pos-${m.machine_id}`}>
        {m.lon != null && m.lat != null ? `${Number(m.lon).toFixed(6)}, ${Number(m.lat).toFixed(6)}` : 'no position'}
        {m.status === 'offline' && m.lon != null ? ' (last known)' : ''}
        {m.lon != null && m.lat != null && (
          <button
            type="button"
            className="link"
            aria-pressed={followed}
            data-testid={`fleet-follow-${m.machine_id}`}
            title="Keep this machine in view on the map"
            onClick={onFollow}
          >
            {followed ? 'following' : 'follow on map'}
          </button>
        )}
      </div>
    </li>
  );
}

function Alerts(props: { groups: AlertGroup[]; fleet: Fleet; onAck: (g: AlertGroup) => void }) {
  const { groups, fleet, onAck } = props;
  const name = (id?: number) => (id != null ? (fleet.get(id)?.name ?? `#${id}`) : '');
  return (
    <>
      <h3>
        Alerts <span className="badge" data-testid="alert-count">{openGroupCount(groups)}</span>
      </h3>
      <ul className="list" data-testid="alert-list">
        {groups.map((g) => {
          const key = groupKey(g);
          const acked = g.unacknowledged === 0;
          return (
            <li key={key} className={acked ? 'muted' : 'alert'} data-testid={`alert-group-${key}`}>
              <strong>{groupLabel(g)}</strong> · {name(g.machine_id)}
              {g.job_id != null && <> · job #{g.job_id}</>}
              {g.message && <div className="small">{g.message}</div>}
              <div className="muted small">
                {g.first_started_at ? new Date(String(g.first_started_at)).toLocaleString() : ''}
                {g.count > 1 && g.last_started_at ? ` – ${new Date(String(g.last_started_at)).toLocaleString()}` : ''}
              </div>
              {!acked && (
                <button className="link" data-testid={`ack-group-${key}`} data-write="" onClick={() => onAck(g)}>
                  {g.unacknowledged > 1 ? `acknowledge all ${g.unacknowledged}` : 'acknowledge'}
                </button>
              )}
            </li>
          );
        })}
      </ul>
    </>
  );
}
