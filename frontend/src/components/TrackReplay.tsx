import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client } from '../api/client';
import { bearingDeg } from '../lib/geo';
import { normaliseTrack, type TrackPoint } from '../lib/track';
import { formatRate } from '../lib/units';
import { setGeoJSON } from '../map/setup';

/** Records per page: the page holds at most this many points (not a whole job's 200k). */
export const PAGE = 2000;
const EMPTY: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };

/**
 * Replay of a job's as-applied records, read one page at a time (GET /jobs/{id}/as-applied,
 * ``PAGE`` records): the slider spans every record, the page around its position is fetched
 * when it moves, and the map shows that page's trail up to the position (sources ``trail``
 * and ``replay``, which the screen created). While following, the last page is re-read on
 * every ``tick`` (new records of a running job). The cells themselves come as vector tiles.
 */
export function TrackReplay({ jobId, map, tick }: { jobId: number; map: maplibregl.Map | null; tick: number }) {
  const [total, setTotal] = useState<number | null>(null);
  const [page, setPage] = useState<{ offset: number; points: TrackPoint[] }>({ offset: 0, points: [] });
  const [idx, setIdx] = useState(-1);
  const [follow, setFollow] = useState(true);
  const want = useRef(0);

  const load = async (offset: number) => {
    const path = { job_id: jobId };
    want.current = offset;
    const r = await call(client.GET('/api/v1/jobs/{job_id}/as-applied', { params: { path, query: { limit: PAGE, offset } } }));
    if (want.current !== offset) return null; // a later move asked for another page
    setTotal(r.total ?? 0);
    setPage({ offset, points: normaliseTrack(r) });
    return r.total ?? 0;
  };

  // Following: the newest page (its total first, from a one-record page).
  useEffect(() => {
    if (!follow) return;
    void (async () => {
      const r = await call(
        client.GET('/api/v1/jobs/{job_id}/as-applied', { params: { path: { job_id: jobId }, query: { limit: 1, offset: 0 } } }),
      ).catch(() => null);
      const n = r?.total ?? 0;
      setTotal(n);
      if (n > 0) {
        await load(Math.floor((n - 1) / PAGE) * PAGE).catch(() => undefined);
        setIdx(n - 1);
      }
    })();
  }, [jobId, tick, follow]); // eslint-disable-line react-hooks/exhaustive-deps

  // A move outside the page on screen fetches the page around it.
  useEffect(() => {
    if (idx < 0 || (idx >= page.offset && idx < page.offset + page.points.length)) return;
    const t = setTimeout(() => void load(Math.floor(idx / PAGE) * PAGE).catch(() => undefined), 120);
    return () => clearTimeout(t);
  }, [idx]); // eslint-disable-line react-hooks/exhaustive-deps

  const local = idx - page.offset;
  const cur = local >= 0 && local < page.points.length ? page.points[local] : undefined;
  useEffect(() => {
    if (!map) return;
    const upto = page.points.slice(0, Math.max(0, local + 1)).filter((p) => p.lon != null && p.lat != null);
    setGeoJSON(map, 'trail', {
      type: 'Feature',
      properties: {},
      geometry: { type: 'LineString', coordinates: upto.map((p) => [p.lon!, p.lat!]) },
    });
    const n = upto.length;
    const heading = n > 1 ? bearingDeg([upto[n - 2].lon!, upto[n - 2].lat!], [upto[n - 1].lon!, upto[n - 1].lat!]) : 0;
    setGeoJSON(
      map,
      'replay',
      cur?.lon != null && cur.lat != null
        ? { type: 'Feature', properties: { heading: cur.heading_deg ?? heading }, geometry: { type: 'Point', coordinates: [cur.lon, cur.lat] } }
        : EMPTY,
    );
  }, [map, page, local, cur]);

  const n = total ?? 0;
  return (
    <div className="screen-only">
      <h3>Track replay</h3>
      <input
        data-testid="replay-slider"
        type="range"
        aria-label="Replay position"
        min={0}
        max={Math.max(0, n - 1)}
        value={Math.max(0, idx)}
        disabled={n === 0}
        onChange={(e) => {
          const v = Number(e.target.value);
          setFollow(v >= n - 1);
          setIdx(v);
        }}
        style={{ width: '100%' }}
      />
      <p className="muted small" data-testid="replay-time">
        {cur
          ? `${new Date(cur.t * 1000).toISOString().replace('T', ' ').slice(0, 19)} UTC · target ${formatRate(cur.target_rate_kg_ha)} · applied ${formatRate(cur.applied_rate_kg_ha)}`
          : total == null
            ? 'loading records…'
            : n === 0
              ? 'no records yet'
              : 'loading this part of the track…'}
      </p>
      <p className="muted small" data-testid="report-points">
        {total == null ? '… as-applied records' : `${n} as-applied records`}
        {n > PAGE ? ` (read ${PAGE.toLocaleString()} at a time)` : ''}
      </p>
    </div>
  );
}
