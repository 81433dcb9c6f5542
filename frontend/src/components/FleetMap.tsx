/**
 * The fleet's map, composed of overlays: fields as context, live trails, the running jobs'
 * coverage, machines (status colour, heading) and their names as labels.
 *
 * Labels are DOM markers, not a symbol layer: the offline base style has no glyph server.
 * Coverage is the job's own as-applied cell tiles, painted by the report's own rule for an
 * applied cell (`COVERED`), re-requested at most every `COVERAGE_REFRESH_MS` while the
 * job's progress moves and once more when its state changes (the end of a job shows exactly
 * the report's applied cells, and stays on the map) (a busy job sends several messages a second, and a tile request after
 * new records rebuilds the job's report: at 2 s the fleet page slowed the ingest of a
 * simulated job on the shared 2-core test machine).
 */
import { useEffect, useMemo, useRef, useState } from 'react';
import * as maplibregl from 'maplibre-gl';
import { useFields } from '../api/hooks';
import type { Fleet } from '../lib/fleet';
import { trailSegments, type TrailPoint } from '../lib/trail';
import { bboxOf } from '../lib/geo';
import { useMap } from '../map/context';
import { MapView } from '../map/MapView';
import { CellGrid, FieldBoundary, FitBounds, Follow, Machines, Track } from '../map/overlays';
import { absoluteApiUrl } from '../map/setup';

export const COVERAGE_REFRESH_MS = 5000;
/** The fleet screen's side panel, which may lie over the map on a tablet. */
const PANEL = '.split > .panel[aria-label="Fleet"]';
/**
 * Applied cells in amber, the rest of the job's grid clear. An applied cell is the report's
 * (`JobReport.cells_applied`): one the prescription asks fertilizer for (planned rate > 0)
 * that received some (applied mass M2 > 0, seed 001 eq. 17; the tile's applied rate is M2
 * over the cell's area). Records alone do not make a cell applied: a pass with the meter at
 * 0 or over an unprescribed cell is driven, not applied.
 */
export const COVERED_FILTER = [
  'all',
  ['>', ['to-number', ['get', 'target_rate'], 0], 0],
  ['>', ['to-number', ['get', 'applied_rate'], 0], 0],
];
const COVERED = ['case', COVERED_FILTER, '#f0b400', 'rgba(0,0,0,0)'];

/** One DOM label per machine with a position, kept in step with the fleet. */
function MachineLabels({ fleet }: { fleet: Fleet }) {
  const map = useMap();
  const markers = useRef(new Map<number, maplibregl.Marker>());
  useEffect(() => {
    if (!map) return;
    const seen = new Set<number>();
    for (const m of fleet.values()) {
      if (m.lon == null || m.lat == null) continue;
      seen.add(m.machine_id);
      let mk = markers.current.get(m.machine_id);
      if (!mk) {
        const el = document.createElement('div');
        el.dataset.testid = `map-label-${m.machine_id}`;
        mk = new maplibregl.Marker({ element: el, anchor: 'bottom', offset: [0, -13] }).setLngLat([m.lon, m.lat]).addTo(map);
        markers.current.set(m.machine_id, mk);
      }
      const el = mk.getElement();
      // classList, not className: the marker's own classes position it
      el.classList.add('machine-label');
      el.classList.toggle('offline', m.status === 'offline');
      el.textContent = m.name ?? `#${m.machine_id}`;
      mk.setLngLat([m.lon, m.lat]);
    }
    for (const [id, mk] of markers.current)
      if (!seen.has(id)) {
        mk.remove();
        markers.current.delete(id);
      }
  }, [map, fleet]);
  useEffect(
    () => () => {
      for (const mk of markers.current.values()) mk.remove();
      markers.current.clear();
    },
    [map],
  );
  return null;
}

/** A running job's covered cells; its tiles are re-requested when progress has moved. */
function LiveCoverage({ jobId, progress, state }: { jobId: number; progress: number; state: string }) {
  const key = `${state}:${progress}`;
  const latest = useRef(key);
  latest.current = key;
  const [shown, setShown] = useState(key);
  useEffect(() => {
    const t = setInterval(() => setShown(latest.current), COVERAGE_REFRESH_MS);
    return () => clearInterval(t);
  }, []);
  // a change of state (the job ended) shows at once: its cells are final
  useEffect(() => setShown(latest.current), [state]);
  return (
    <CellGrid
      id={`coverage-${jobId}`}
      tiles={absoluteApiUrl(`/api/v1/tiles/jobs/${jobId}/{z}/{x}/{y}.mvt`)}
      color={COVERED}
      opacity={0.6}
      refreshKey={shown}
    />
  );
}

/**
 * The fleet's map: fitted once to the machines, then left where the user puts it, except
 * that a followed machine (`follow`, picked in the list) is kept in view.
 */
export function FleetMap(props: { fleet: Fleet; trails: Map<number, TrailPoint[]>; follow?: number | null }) {
  const { fleet, trails, follow } = props;
  const followed = follow != null ? fleet.get(follow) : undefined;
  const fields = useFields({ limit: 500 });
  const machines = useMemo(() => [...fleet.values()], [fleet]);
  const paths = useMemo(() => [...trails.values()].flatMap(trailSegments), [fleet, trails]); // eslint-disable-line react-hooks/exhaustive-deps
  // a job's coverage stays after it ended (job_id is the machine's last job)
  const covering = machines.filter((m) => m.job_id != null && m.job_state != null && m.job_state !== 'cancelled');
  const bbox = useMemo(
    () =>
      bboxOf({
        type: 'MultiPoint',
        coordinates: machines.filter((m) => m.lon != null && m.lat != null).map((m) => [m.lon, m.lat]),
      }),
    [machines],
  );
  return (
    <MapView name="fleet">
      <FieldBoundary id="fields" data={fields.data} />
      {covering.map((m) => (
        <LiveCoverage key={m.job_id} jobId={m.job_id as number} progress={m.progress ?? 0} state={m.job_state as string} />
      ))}
      <Track id="trails" paths={paths} width={2} opacity={0.6} />
      <Machines machines={machines} onClick={(id) => (location.hash = `/machines/${id}`)} />
      <MachineLabels fleet={fleet} />
      <FitBounds bbox={bbox} once padding={60} maxZoom={16} avoid={PANEL} />
      <Follow
        followKey={follow ?? null}
        point={followed?.lon != null && followed.lat != null ? [followed.lon, followed.lat] : null}
        avoid={PANEL}
      />
    </MapView>
  );
}
