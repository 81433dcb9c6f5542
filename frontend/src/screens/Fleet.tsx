import { useCallback, useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client } from '../api/client';
import { ErrorBox } from '../components/Status';
import { statusColor } from '../lib/colors';
import { applyLive, fromStatusItem, type Fleet } from '../lib/fleet';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { compass, formatPercent, formatRate, formatSpeed } from '../lib/units';
import { useLive } from '../live';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import { ackBody, groupKey, groupLabel, markAcknowledged, openGroupCount, type AlertGroup } from '../lib/alerts';

const TRAIL = 300;

function toFC(fleet: Fleet): GeoJSON.FeatureCollection {
  return {
    type: 'FeatureCollection',
    features: [...fleet.values()]
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

/** Live fleet: positions over WebSocket, status colours, heading arrows, job progress, alerts. */
export function FleetScreen() {
  const [fleet, setFleet] = useState<Fleet>(new Map());
  const [groups, setGroups] = useState<AlertGroup[]>([]);
  const [error, setError] = useState<unknown>(null);
  const trails = useRef(new Map<number, [number, number][]>());
  const mapRef = useRef<maplibregl.Map | null>(null);
  const fitted = useRef(false);

  const loadStatus = useCallback(async () => {
    try {
      const r = await call(client.GET('/api/v1/machines/status'));
      setFleet(new Map(r.items.map((o) => [o.machine_id, fromStatusItem(o)])));
    } catch (e) {
      setError(e);
    }
  }, []);
  const loadAlerts = useCallback(async () => {
    try {
      setGroups((await call(client.GET('/api/v1/alerts/groups', { params: { query: { limit: 50 } } }))).items);
    } catch (e) {
      setError(e);
    }
  }, []);

  useEffect(() => {
    void loadStatus();
    void loadAlerts();
    const t = setInterval(() => void loadAlerts(), 15_000);
    return () => clearInterval(t);
  }, [loadStatus, loadAlerts]);

  const live = useLive((msg) => {
    if (msg.type === 'alert') void loadAlerts();
    if (msg.type === 'position' && typeof msg.lon === 'number' && typeof msg.lat === 'number') {
      const id = Number(msg.machine_id);
      const tr = trails.current.get(id) ?? [];
      tr.push([msg.lon, msg.lat]);
      if (tr.length > TRAIL) tr.splice(0, tr.length - TRAIL);
      trails.current.set(id, tr);
    }
    setFleet((cur) => applyLive(cur, msg));
  });

  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    const fc = toFC(fleet);
    setGeoJSON(map, 'machines', fc);
    setGeoJSON(map, 'trails', {
      type: 'FeatureCollection',
      features: [...trails.current.entries()]
        .filter(([, c]) => c.length > 1)
        .map(([id, c]) => ({ type: 'Feature', properties: { machine_id: id }, geometry: { type: 'LineString', coordinates: c } })),
    });
    if (!fitted.current && fc.features.length) {
      fitTo(map, bboxOf(fc), 200);
      if (map.getZoom() > 16) map.setZoom(16);
      fitted.current = true;
    }
  }, [fleet]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    // Fields as context under the machines.
    setGeoJSON(map, 'fields', { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'fields-fill', type: 'fill', source: 'fields', paint: { 'fill-color': '#4c9a2a', 'fill-opacity': 0.15 } });
    map.addLayer({ id: 'fields-line', type: 'line', source: 'fields', paint: { 'line-color': '#2d5e16', 'line-width': 1 } });
    call(client.GET('/api/v1/fields', { params: { query: { limit: 500 } } }))
      .then((fc) => setGeoJSON(map, 'fields', asGeoJSON(fc)))
      .catch(() => undefined);
    setGeoJSON(map, 'trails', { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'trails', type: 'line', source: 'trails', paint: { 'line-color': '#1e3a8a', 'line-width': 2, 'line-opacity': 0.6 } });
    setGeoJSON(map, 'machines', toFC(fleet));
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
  };

  const list = [...fleet.values()].sort((a, b) => a.machine_id - b.machine_id);
  const name = (id?: number) => (id != null ? (fleet.get(id)?.name ?? `#${id}`) : '');
  const ackAll = async (g: AlertGroup) => {
    try {
      await call(client.POST('/api/v1/alerts/ack', { body: ackBody(g) }));
      setGroups((cur) => markAcknowledged(cur, groupKey(g)));
    } catch (e) {
      setError(e);
    }
  };
  return (
    <div className="split">
      <aside className="panel">
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
          {list.map((m) => (
            <li key={m.machine_id} data-testid={`fleet-machine-${m.machine_id}`}>
              <span className="dot" style={{ background: statusColor(m.status) }} />
              <a href={`#/machines/${m.machine_id}`}>{m.name ?? `Machine #${m.machine_id}`}</a>{' '}
              <span className="muted" data-testid={`machine-status-${m.machine_id}`}>
                {m.status}
              </span>
              <div className="muted small">
                {formatSpeed(m.speed_m_s)} · heading{' '}
                {m.heading_deg != null ? `${Math.round(m.heading_deg)}° ${compass(m.heading_deg)}` : '–'}
                {m.job_id != null && (
                  <>
                    {' '}
                    · <a href={`#/jobs/${m.job_id}`}>job #{m.job_id}</a> {m.job_state ?? ''}{' '}
                    <span data-testid={`machine-progress-${m.machine_id}`}>{m.progress != null ? formatPercent(m.progress) : ''}</span>
                  </>
                )}
              </div>
              {m.progress != null && (
                <progress max={1} value={m.progress} style={{ width: '100%' }} data-testid={`machine-progressbar-${m.machine_id}`} />
              )}
              {(m.ndvi != null || m.depth_mm != null) && (
                <div className="small" data-testid={`machine-sensor-${m.machine_id}`}>
                  {m.ndvi != null && `NDVI ${m.ndvi.toFixed(2)} · ${formatRate(m.applied_rate_kg_ha, 0)}`}
                  {m.depth_mm != null && `depth ${m.depth_mm.toFixed(1)} mm`}
                </div>
              )}
              <div className="muted small" data-testid={`machine-pos-${m.machine_id}`}>
                {m.lon != null && m.lat != null ? `${Number(m.lon).toFixed(6)}, ${Number(m.lat).toFixed(6)}` : 'no position'}
              </div>
            </li>
          ))}
        </ul>
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
                  <button className="link" data-testid={`ack-group-${key}`} data-write="" onClick={() => void ackAll(g)}>
                    {g.unacknowledged > 1 ? `acknowledge all ${g.unacknowledged}` : 'acknowledge'}
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
