import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { api } from '../api';
import { Legend } from '../components/Legend';
import { ErrorBox, isMissingEndpoint, Kv } from '../components/Status';
import {
  classColors,
  DIVERGING,
  legendEntries,
  niceBreaks,
  stepExpression,
  symmetricBreaks,
} from '../lib/colors';
import { bboxOf } from '../lib/geo';
import { indexAtTime, normaliseTrack, type TrackPoint } from '../lib/track';
import { formatArea, formatDuration, formatMass, formatPercent, formatRate } from '../lib/units';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import type { Job } from '../types';
import { pick } from '../types';

type View = 'applied' | 'accuracy';
const EMPTY: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };

/** Adds error_pct = (applied - target) / target * 100 where the server did not. */
export function withAccuracy(fc: GeoJSON.FeatureCollection): GeoJSON.FeatureCollection {
  return {
    ...fc,
    features: fc.features.map((f) => {
      const p = { ...(f.properties ?? {}) } as Record<string, unknown>;
      if (p.error_pct == null) {
        const a = Number(p.applied_rate_kg_ha ?? p.applied_kg_ha ?? p.rate_kg_ha);
        const t = Number(p.target_rate_kg_ha ?? p.target_kg_ha);
        if (Number.isFinite(a) && Number.isFinite(t) && t > 0) p.error_pct = ((a - t) / t) * 100;
      }
      if (p.applied_rate_kg_ha == null && p.applied_kg_ha != null) p.applied_rate_kg_ha = p.applied_kg_ha;
      return { ...f, properties: p };
    }),
  };
}

/** As-applied map, per-cell accuracy, totals, and a replay of the machine's track. */
export function JobReport({ jobId }: { jobId: number }) {
  const [job, setJob] = useState<Job | null>(null);
  const [report, setReport] = useState<Record<string, unknown> | null>(null);
  const [applied, setApplied] = useState<GeoJSON.FeatureCollection>(EMPTY);
  const [track, setTrack] = useState<TrackPoint[]>([]);
  const [view, setView] = useState<View>('applied');
  const [tIdx, setTIdx] = useState(-1);
  const [error, setError] = useState<unknown>(null);
  const [missing, setMissing] = useState(false);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const fitted = useRef(false);

  const load = useCallback(async () => {
    try {
      const j = await api.get<Job>(`/jobs/${jobId}`);
      setJob(j);
      const [rep, aa] = await Promise.all([
        api.get<Record<string, unknown>>(`/jobs/${jobId}/report`).catch((e) => {
          if (isMissingEndpoint(e)) setMissing(true);
          return null;
        }),
        api.get<GeoJSON.FeatureCollection>(`/jobs/${jobId}/as-applied`).catch(() => null),
      ]);
      setReport(rep);
      const cells = (rep?.cells as GeoJSON.FeatureCollection | undefined)?.features ? (rep!.cells as GeoJSON.FeatureCollection) : null;
      const fc = aa?.features ? aa : cells;
      if (fc) setApplied(withAccuracy(fc));
      const tr = await api
        .get(`/machines/${j.machine_id}/track?job_id=${jobId}&limit=20000`)
        .catch(() => null);
      const pts = normaliseTrack(tr).filter((p) => p.job_id == null || p.job_id === jobId);
      setTrack(pts);
      setTIdx((cur) => (cur < 0 || cur >= pts.length - 2 ? pts.length - 1 : cur));
    } catch (e) {
      setError(e);
    }
  }, [jobId]);

  useEffect(() => {
    void load();
    const t = setInterval(() => void load(), 5000);
    return () => clearInterval(t);
  }, [load]);

  const appliedVals = applied.features.map((f) => Number(f.properties?.applied_rate_kg_ha)).filter(Number.isFinite);
  const errVals = applied.features.map((f) => Number(f.properties?.error_pct)).filter(Number.isFinite);
  let aLo = Infinity;
  let aHi = -Infinity;
  for (const v of appliedVals) {
    if (v < aLo) aLo = v;
    if (v > aHi) aHi = v;
  }
  const aBreaks = useMemo(() => niceBreaks(aLo <= aHi ? aLo : 0, aLo <= aHi ? aHi : 1000, 6), [aLo, aHi]);
  let eMax = 10;
  for (const v of errVals) if (Math.abs(v) > eMax) eMax = Math.abs(v);
  const aColors = classColors(aBreaks.length - 1);
  const eBreaks = symmetricBreaks(Math.min(50, eMax), 6);
  const eColors = classColors(6, DIVERGING);
  const prop = view === 'applied' ? 'applied_rate_kg_ha' : 'error_pct';
  const expr = view === 'applied' ? stepExpression(prop, aBreaks, aColors) : stepExpression(prop, eBreaks, eColors);
  const legend =
    view === 'applied'
      ? legendEntries(aBreaks, aColors, (v) => v.toFixed(0))
      : legendEntries(eBreaks, eColors, (v) => `${v > 0 ? '+' : ''}${v.toFixed(0)} %`);

  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    setGeoJSON(map, 'applied', applied);
    for (const l of ['applied-fill', 'applied-pts']) {
      if (!map.getLayer(l)) continue;
      map.setPaintProperty(l, l === 'applied-fill' ? 'fill-color' : 'circle-color', expr as never);
    }
    if (!fitted.current && applied.features.length) {
      fitTo(map, bboxOf(applied));
      fitted.current = true;
    }
  }, [applied, JSON.stringify(expr)]); // eslint-disable-line react-hooks/exhaustive-deps

  const cur = tIdx >= 0 ? track[tIdx] : undefined;
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    const upto = track.slice(0, tIdx + 1).filter((p) => p.lon != null && p.lat != null);
    setGeoJSON(map, 'trail', {
      type: 'Feature',
      properties: {},
      geometry: { type: 'LineString', coordinates: upto.map((p) => [p.lon!, p.lat!]) },
    });
    setGeoJSON(
      map,
      'replay',
      cur?.lon != null && cur.lat != null
        ? {
            type: 'Feature',
            properties: { heading: cur.heading_deg ?? 0 },
            geometry: { type: 'Point', coordinates: [cur.lon, cur.lat] },
          }
        : EMPTY,
    );
    if (!fitted.current && upto.length > 1) {
      fitTo(map, bboxOf({ type: 'LineString', coordinates: upto.map((p) => [p.lon!, p.lat!]) }));
      fitted.current = true;
    }
  }, [track, tIdx, cur]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'applied', EMPTY);
    map.addLayer({
      id: 'applied-fill',
      type: 'fill',
      source: 'applied',
      filter: ['==', ['geometry-type'], 'Polygon'],
      paint: { 'fill-color': '#999', 'fill-opacity': 0.85 },
    });
    map.addLayer({
      id: 'applied-pts',
      type: 'circle',
      source: 'applied',
      filter: ['==', ['geometry-type'], 'Point'],
      paint: { 'circle-radius': 3, 'circle-color': '#999' },
    });
    setGeoJSON(map, 'trail', EMPTY);
    map.addLayer({ id: 'trail', type: 'line', source: 'trail', paint: { 'line-color': '#111', 'line-width': 1.5, 'line-opacity': 0.6 } });
    setGeoJSON(map, 'replay', EMPTY);
    map.addLayer({
      id: 'replay',
      type: 'symbol',
      source: 'replay',
      layout: {
        'icon-image': 'arrow',
        'icon-rotate': ['get', 'heading'],
        'icon-rotation-alignment': 'map',
        'icon-size': 0.8,
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': '#d7263d', 'icon-halo-color': '#fff', 'icon-halo-width': 2 },
    });
  };

  const r = { ...(report ?? {}), ...((report?.totals as Record<string, unknown>) ?? {}) } as Record<string, unknown>;
  const cov = pick(r, 'coverage', 'coverage_fraction', 'progress');
  return (
    <div className="split">
      <aside className="panel">
        <p>
          <a href="#/jobs">← Jobs</a>
        </p>
        <h2>Job #{jobId} report</h2>
        <ErrorBox error={error} />
        {missing && <p className="muted">Reports are not available on this server yet.</p>}
        <Kv
          items={[
            ['State', job?.state ?? '–', 'report-state'],
            ['Machine', job ? <a href={`#/machines/${job.machine_id}`}>#{job.machine_id}</a> : '–'],
            ['Prescription', job ? <a href={`#/prescriptions/${job.prescription_id}`}>#{job.prescription_id}</a> : '–'],
            ['Cells done', String(pick(r, 'cells_done', 'cells_applied', 'cells_covered') ?? '–') + (pick(r, 'cell_count', 'cells_total') != null ? ` / ${pick(r, 'cell_count', 'cells_total')}` : ''), 'report-cells'],
            ['Coverage', cov != null ? formatPercent(cov > 1 ? cov / 100 : cov) : '–', 'report-coverage'],
            ['Area applied', formatArea(pick(r, 'area_applied_m2', 'applied_area_m2', 'area_m2')), 'report-area'],
            ['Product (target)', formatMass(pick(r, 'target_kg', 'product_target_kg', 'total_target_kg'))],
            ['Product (applied)', formatMass(pick(r, 'applied_kg', 'product_applied_kg', 'total_applied_kg')), 'report-applied-kg'],
            ['Mean |error|', pick(r, 'mean_abs_error_pct') != null ? `${pick(r, 'mean_abs_error_pct')!.toFixed(1)} %` : '–'],
            ['Mean rate', formatRate(pick(r, 'mean_applied_rate_kg_ha', 'applied_rate_mean_kg_ha'))],
            ['Duration', formatDuration(pick(r, 'duration_s'))],
            ['Records', String(track.length), 'report-records'],
          ]}
        />
        <div className="row" role="group">
          <button data-testid="view-applied" className={view === 'applied' ? 'on' : ''} onClick={() => setView('applied')}>
            As applied
          </button>
          <button data-testid="view-accuracy" className={view === 'accuracy' ? 'on' : ''} onClick={() => setView('accuracy')}>
            Accuracy
          </button>
        </div>
        <Legend entries={legend} title={view === 'applied' ? 'Applied (kg/ha)' : 'Applied vs target'} testid="report-legend" />
        <p className="muted" data-testid="report-features">
          {applied.features.length} as-applied features
        </p>
        <h3>Track replay</h3>
        <input
          data-testid="replay-slider"
          type="range"
          min={0}
          max={Math.max(0, track.length - 1)}
          value={Math.max(0, tIdx)}
          disabled={track.length === 0}
          onChange={(e) => setTIdx(Number(e.target.value))}
          style={{ width: '100%' }}
        />
        <p className="muted small" data-testid="replay-time">
          {cur
            ? `${new Date(cur.t * 1000).toISOString().replace('T', ' ').slice(0, 19)} UTC · ${
                cur.target_rate_kg_ha != null ? formatRate(cur.target_rate_kg_ha) : ''
              } → ${cur.applied_rate_kg_ha != null ? formatRate(cur.applied_rate_kg_ha) : ''}`
            : 'no track yet'}
        </p>
        {track.length > 0 && (
          <button
            className="secondary"
            onClick={() => {
              if (!track.length) return;
              const t0 = track[tIdx]?.t ?? track[0].t;
              setTIdx(Math.max(0, indexAtTime(track, t0 - 60)));
            }}
          >
            −1 min
          </button>
        )}
      </aside>
      <MapView name="report" onReady={onReady} />
    </div>
  );
}
