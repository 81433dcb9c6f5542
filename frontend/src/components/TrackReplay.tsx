import { useEffect, useMemo, useRef, useState } from 'react';
import { useQueryClient } from '@tanstack/react-query';
import { qk, useAsApplied } from '../api/hooks';
import { bearingDeg } from '../lib/geo';
import { normaliseTrack, type TrackPoint } from '../lib/track';
import { formatRate } from '../lib/units';
import { Track, type TrackHead } from '../map/overlays';

/** Records per page: the page holds at most this many points (not a whole job's 200k). */
export const PAGE = 2000;
/** A dragged slider asks for its page once it has rested this long. */
const SETTLE_MS = 120;

export type Replay = ReturnType<typeof useTrackReplay>;

/**
 * Replay of a job's as-applied records, read one page at a time (GET /jobs/{id}/as-applied,
 * ``PAGE`` records, through the hooks' cache): the slider spans every record (the count from
 * a one-record page), the page around its position is read when it rests, and the trail runs
 * up to the position. While following the newest record (the slider at its end), the count
 * and the last page are read again whenever `tick` changes (a running job's new records).
 * The cells themselves come as vector tiles. The screen shows `<TrackReplay>` (the controls)
 * and `<ReplayTrail>` (in its MapView) from the same `useTrackReplay`.
 */
export function useTrackReplay(jobId: number, tick: number) {
  /** The slider's record; null = following the newest one. */
  const [pos, setPos] = useState<number | null>(null);
  const countQ = useAsApplied(jobId, { limit: 1, offset: 0 });
  const total = countQ.data ? (countQ.data.total ?? 0) : null;
  const n = total ?? 0;
  const following = pos == null;

  const want = Math.floor(Math.max(0, pos ?? n - 1) / PAGE) * PAGE;
  const [offset, setOffset] = useState(want);
  useEffect(() => {
    if (want === offset) return;
    if (following) return setOffset(want);
    const t = setTimeout(() => setOffset(want), SETTLE_MS);
    return () => clearTimeout(t);
  }, [want, offset, following]);
  const pageQ = useAsApplied(jobId, { limit: PAGE, offset }, { enabled: n > 0 });
  const points = useMemo(() => (pageQ.data ? normaliseTrack(pageQ.data) : []), [pageQ.data]);

  // New records of a running job: count and last page again (not on the first answer).
  const qc = useQueryClient();
  const seen = useRef(tick);
  useEffect(() => {
    if (tick === seen.current) return;
    const first = seen.current === 0;
    seen.current = tick;
    if (!first && following) void qc.invalidateQueries({ queryKey: [...qk.job(jobId), 'as-applied'] });
  }, [tick, following, jobId, qc]);

  // Following: the newest record of the page on screen (the count may run a little ahead).
  const idx = following ? (pageQ.data && offset === want ? Math.min(n - 1, offset + points.length - 1) : -1) : pos;
  const local = idx - offset;
  const cur: TrackPoint | undefined = local >= 0 && local < points.length ? points[local] : undefined;
  const upto = useMemo(
    () =>
      points
        .slice(0, Math.max(0, local + 1))
        .filter((p) => p.lon != null && p.lat != null)
        .map((p): [number, number] => [p.lon!, p.lat!]),
    [points, local],
  );
  const paths = useMemo(() => [upto], [upto]);
  const k = upto.length;
  const head: TrackHead | null =
    cur?.lon != null && cur.lat != null
      ? { lon: cur.lon, lat: cur.lat, heading: cur.heading_deg ?? (k > 1 ? bearingDeg(upto[k - 2], upto[k - 1]) : 0) }
      : null;
  /** The slider moved: the end follows the newest record again. */
  const seek = (v: number) => setPos(v >= n - 1 ? null : v);
  return { total, idx, cur, paths, head, seek };
}

/** The replay's trail and position arrow (inside the report's MapView). */
export function ReplayTrail({ replay }: { replay: Replay }) {
  return <Track id="trail" paths={replay.paths} head={replay.head} color="#111" width={1.2} opacity={0.55} />;
}

/** The replay's slider and what it stands on (the screen, not the printed page). */
export function TrackReplay({ replay }: { replay: Replay }) {
  const { total, idx, cur, seek } = replay;
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
        onChange={(e) => seek(Number(e.target.value))}
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
