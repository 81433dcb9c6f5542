import { useCallback, useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { api } from '../api';
import { ErrorBox, isMissingEndpoint } from '../components/Status';
import { statusColor } from '../lib/colors';
import { bboxOf } from '../lib/geo';
import { compass, formatPercent, formatSpeed } from '../lib/units';
import { useLive, type LiveMessage } from '../live';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import type { Alert, MachineStatus } from '../types';
import { listOf } from '../types';

function toFC(ms: Map<number, MachineStatus>): GeoJSON.FeatureCollection {
  return {
    type: 'FeatureCollection',
    features: [...ms.values()]
      .filter((m) => m.lon != null && m.lat != null)
      .map((m) => ({
        type: 'Feature',
        id: m.machine_id,
        properties: {
          machine_id: m.machine_id,
          heading: m.heading_deg ?? 0,
          color: statusColor(m.status),
          has_heading: m.heading_deg != null,
        },
        geometry: { type: 'Point', coordinates: [m.lon as number, m.lat as number] },
      })),
  };
}

function normStatus(m: Record<string, unknown>): MachineStatus {
  const id = Number(m.machine_id ?? m.id);
  return { ...m, machine_id: id } as MachineStatus;
}

/** Live fleet: positions over WebSocket, status colours, heading arrows, job progress, alerts. */
export function FleetScreen() {
  const [machines, setMachines] = useState<Map<number, MachineStatus>>(new Map());
  const [alerts, setAlerts] = useState<Alert[]>([]);
  const [error, setError] = useState<unknown>(null);
  const [missing, setMissing] = useState(false);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const fitted = useRef(false);

  const loadStatus = useCallback(async () => {
    try {
      const r = await api.get('/machines/status');
      const m = new Map<number, MachineStatus>();
      for (const s of listOf<Record<string, unknown>>(r)) {
        const n = normStatus(s);
        m.set(n.machine_id, n);
      }
      setMachines(m);
    } catch (e) {
      if (isMissingEndpoint(e)) {
        setMissing(true);
        // Fall back to the plain machine list so the screen still shows the fleet.
        try {
          const r = await api.get('/machines');
          setMachines(new Map(listOf<Record<string, unknown>>(r).map((x) => [Number(x.id), normStatus(x)])));
        } catch {
          /* nothing to show */
        }
      } else setError(e);
    }
  }, []);
  const loadAlerts = useCallback(async () => {
    try {
      setAlerts(listOf<Alert>(await api.get('/alerts')));
    } catch (e) {
      if (!isMissingEndpoint(e)) setError(e);
    }
  }, []);

  useEffect(() => {
    void loadStatus();
    void loadAlerts();
    const t = setInterval(() => void loadAlerts(), 15_000);
    return () => clearInterval(t);
  }, [loadStatus, loadAlerts]);

  const live = useLive((msg: LiveMessage) => {
    if (msg.type === 'alert') {
      const a = (msg.alert ?? msg) as Alert;
      setAlerts((cur) => [a, ...cur.filter((x) => x.id !== a.id)]);
      return;
    }
    const id = Number(msg.machine_id);
    if (!Number.isFinite(id)) return;
    setMachines((cur) => {
      const next = new Map(cur);
      const prev = next.get(id) ?? { machine_id: id };
      const upd: MachineStatus = { ...prev, ...(msg as Record<string, unknown>), machine_id: id };
      if (msg.type === 'position' && !msg.status && !prev.status) upd.status = 'working';
      delete (upd as Record<string, unknown>).type;
      next.set(id, upd);
      return next;
    });
  });

  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    const fc = toFC(machines);
    setGeoJSON(map, 'machines', fc);
    if (!fitted.current && fc.features.length) {
      fitTo(map, bboxOf(fc), 120);
      fitted.current = true;
    }
  }, [machines]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'machines', toFC(machines));
    map.addLayer({
      id: 'machines-dot',
      type: 'circle',
      source: 'machines',
      paint: { 'circle-radius': 11, 'circle-color': ['get', 'color'], 'circle-stroke-color': '#fff', 'circle-stroke-width': 2 },
    });
    map.addLayer({
      id: 'machines-heading',
      type: 'symbol',
      source: 'machines',
      filter: ['==', ['get', 'has_heading'], true],
      layout: {
        'icon-image': 'arrow',
        'icon-rotate': ['get', 'heading'],
        'icon-rotation-alignment': 'map',
        'icon-size': 0.5,
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': '#ffffff' },
    });
    map.on('click', 'machines-dot', (e) => {
      const id = e.features?.[0]?.properties?.machine_id;
      if (id != null) location.hash = `/machines/${id}`;
    });
    const fc = toFC(machines);
    if (fc.features.length) {
      fitTo(map, bboxOf(fc), 120);
      fitted.current = true;
    }
  };

  const list = [...machines.values()].sort((a, b) => a.machine_id - b.machine_id);
  const open = alerts.filter((a) => !a.acknowledged && !a.acknowledged_at);
  return (
    <div className="split">
      <aside className="panel">
        <h2>Fleet</h2>
        <p className="muted">
          Live: <span data-testid="live-state">{live}</span>
        </p>
        {missing && <p className="muted">Fleet status is not available on this server yet.</p>}
        <ErrorBox error={error} />
        <ul className="list" data-testid="fleet-list">
          {list.map((m) => (
            <li key={m.machine_id} data-testid={`fleet-machine-${m.machine_id}`}>
              <span className="dot" style={{ background: statusColor(m.status) }} />
              <a href={`#/machines/${m.machine_id}`}>{m.name ?? `Machine #${m.machine_id}`}</a>{' '}
              <span className="muted" data-testid={`machine-status-${m.machine_id}`}>
                {m.status ?? 'unknown'}
              </span>
              <div className="muted small">
                {formatSpeed(m.speed_filtered_m_s ?? (m.speed_m_s as number | undefined))} · heading{' '}
                {m.heading_deg != null ? `${Math.round(m.heading_deg)}° ${compass(m.heading_deg)}` : '–'}
                {m.job_id != null && (
                  <>
                    {' '}
                    · <a href={`#/jobs/${m.job_id}`}>job #{m.job_id}</a>{' '}
                    <span data-testid={`machine-progress-${m.machine_id}`}>
                      {m.progress != null ? formatPercent(m.progress > 1 ? m.progress / 100 : m.progress) : ''}
                    </span>
                  </>
                )}
              </div>
              <div className="muted small" data-testid={`machine-pos-${m.machine_id}`}>
                {m.lon != null && m.lat != null ? `${Number(m.lon).toFixed(6)}, ${Number(m.lat).toFixed(6)}` : 'no position'}
              </div>
            </li>
          ))}
        </ul>
        <h3>
          Alerts <span className="badge" data-testid="alert-count">{open.length}</span>
        </h3>
        <ul className="list" data-testid="alert-list">
          {alerts.slice(0, 50).map((a) => {
            const acked = Boolean(a.acknowledged || a.acknowledged_at);
            return (
              <li key={a.id} className={acked ? 'muted' : 'alert'} data-testid={`alert-${a.id}`}>
                <strong>{a.kind ?? a.severity ?? 'alert'}</strong> {a.message ?? ''}{' '}
                {a.machine_id != null && <span className="muted">machine #{a.machine_id}</span>}{' '}
                {!acked && (
                  <button
                    className="link"
                    data-testid={`ack-${a.id}`}
                    onClick={async () => {
                      try {
                        await api.post(`/alerts/${a.id}/ack`);
                        setAlerts((cur) => cur.map((x) => (x.id === a.id ? { ...x, acknowledged: true } : x)));
                      } catch (e) {
                        setError(e);
                      }
                    }}
                  >
                    acknowledge
                  </button>
                )}
              </li>
            );
          })}
        </ul>
      </aside>
      <MapView name="fleet" onReady={onReady} />
    </div>
  );
}
