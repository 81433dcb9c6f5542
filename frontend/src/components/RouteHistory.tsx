/**
 * Route history by day: pick a day, see that day's track on a map.
 *
 * The server counts the days in this browser's time zone (`/track/days?tz=`) and gives each
 * day's bounds, which go unchanged into `/track?from&to`: a farm's day is local, and the
 * browser never has to do time-zone arithmetic. A long day is read in pages with a bar.
 */
import { useEffect, useMemo, useState } from 'react';
import { call, client } from '../api/client';
import type { Schemas } from '../api/client';
import { bboxOf } from '../lib/geo';
import { formatDistance } from '../lib/units';
import { useFields } from '../api/hooks';
import { MapView } from '../map/MapView';
import { FieldBoundary, FitBounds, Points, Track } from '../map/overlays';
import { Busy, useBusy } from './Busy';
import { ErrorBox } from './Status';

type TrackDay = Schemas['TrackDay'];
const PAGE = 10_000;
const MAX_POINTS = 200_000;
/** The day's first fix green, its last red. */
const END_COLOR = ['match', ['get', 'end'], 'start', '#2e9e44', '#d7263d'];

function localTz(): string {
  try {
    return Intl.DateTimeFormat().resolvedOptions().timeZone || 'UTC';
  } catch {
    return 'UTC';
  }
}

/** Great-circle length of a lon/lat line (haversine, mean Earth radius): the day's distance. */
export function lineLengthM(coords: [number, number][]): number {
  const R = 6_371_008.8;
  const rad = Math.PI / 180;
  let m = 0;
  for (let i = 1; i < coords.length; i++) {
    const [x1, y1] = coords[i - 1];
    const [x2, y2] = coords[i];
    const a =
      Math.sin(((y2 - y1) * rad) / 2) ** 2 + Math.cos(y1 * rad) * Math.cos(y2 * rad) * Math.sin(((x2 - x1) * rad) / 2) ** 2;
    m += 2 * R * Math.asin(Math.min(1, Math.sqrt(a)));
  }
  return m;
}

export function RouteHistory({ machineId }: { machineId: number }) {
  const tz = useMemo(localTz, []);
  const [days, setDays] = useState<TrackDay[] | null>(null);
  const [day, setDay] = useState('');
  const [coords, setCoords] = useState<[number, number][]>([]);
  const [loaded, setLoaded] = useState<{ n: number; total: number } | null>(null);
  const [error, setError] = useState<unknown>(null);
  const { busy, run } = useBusy();

  useEffect(() => {
    run(() =>
      call(client.GET('/api/v1/machines/{machine_id}/track/days', { params: { path: { machine_id: machineId }, query: { tz } } })),
    )
      .then((r) => {
        setDays(r.items);
        if (r.items.length) setDay(r.items[0].day);
      })
      .catch(setError);
  }, [machineId, tz, run]);

  const chosen = days?.find((d) => d.day === day) ?? null;
  useEffect(() => {
    setCoords([]);
    setLoaded(null);
    if (!chosen) return;
    let stop = false;
    void run(async () => {
      const out: [number, number][] = [];
      let offset: number | null = 0;
      while (offset != null && out.length < MAX_POINTS && !stop) {
        const page: Schemas['PointPage'] = await call(
          client.GET('/api/v1/machines/{machine_id}/track', {
            params: { path: { machine_id: machineId }, query: { from: chosen.start, to: chosen.end, limit: PAGE, offset } },
          }),
        );
        for (const f of page.features) {
          const c = (f.geometry as { coordinates?: number[] } | null)?.coordinates;
          if (c) out.push([c[0], c[1]]);
        }
        if (!stop) setLoaded({ n: out.length, total: page.total });
        offset = page.next_offset ?? null;
      }
      if (!stop) setCoords(out);
    }).catch((e) => !stop && setError(e));
    return () => {
      stop = true;
    };
  }, [machineId, chosen, run]);

  const ends = useMemo(
    (): GeoJSON.FeatureCollection => ({
      type: 'FeatureCollection',
      features: coords.length
        ? [
            { type: 'Feature', properties: { end: 'start' }, geometry: { type: 'Point', coordinates: coords[0] } },
            { type: 'Feature', properties: { end: 'end' }, geometry: { type: 'Point', coordinates: coords[coords.length - 1] } },
          ]
        : [],
    }),
    [coords],
  );
  const paths = useMemo(() => [coords], [coords]);
  const fields = useFields({ limit: 500 });

  const first = days?.[days.length - 1]?.day;
  const last = days?.[0]?.day;
  return (
    <section className="card" aria-labelledby="route-history-title" data-testid="route-history" data-drawn={coords.length}>
      <h3 id="route-history-title">Route history</h3>
      <div className="day-picker">
        <label className="inline">
          Day{' '}
          <input type="date" data-testid="track-day" value={day} min={first} max={last} onChange={(e) => setDay(e.target.value)} />
        </label>
        <Busy busy={busy} label={loaded ? `loading track ${loaded.n} / ${loaded.total} points` : 'loading…'} progress={loaded && loaded.total ? loaded.n / loaded.total : null} testid="track-busy" />
      </div>
      {days && days.length > 0 && (
        <div className="day-picker">
          <span className="muted small">Days with a track:</span>
          <div className="days" role="group" aria-label="Days with a track">
            {days.slice(0, 10).map((d) => (
              <button
                key={d.day}
                type="button"
                className={d.day === day ? 'on' : 'secondary'}
                aria-pressed={d.day === day}
                data-testid={`track-day-${d.day}`}
                onClick={() => setDay(d.day)}
              >
                {d.day}
              </button>
            ))}
          </div>
        </div>
      )}
      <ErrorBox error={error} testid="track-error" />
      <p className="muted small" data-testid="track-summary">
        {days && days.length === 0 && 'No track recorded yet.'}
        {days && days.length > 0 && !chosen && day && `No track on ${day}.`}
        {chosen &&
          `${chosen.points} points · ${new Date(chosen.first_t).toLocaleTimeString()} – ${new Date(chosen.last_t).toLocaleTimeString()}` +
            (coords.length > 1 ? ` · ${formatDistance(lineLengthM(coords))}` : '') +
            ` (${tz})`}
      </p>
      <div className="map-box">
        <MapView name="machine-track" imagery={false}>
          <FieldBoundary id="fields" data={fields.data} />
          <Track id="day-track" paths={paths} width={3} arrows />
          <Points id="day-ends" data={ends} color={END_COLOR} radius={6} />
          <FitBounds bbox={bboxOf(ends)} padding={30} />
        </MapView>
      </div>
    </section>
  );
}
