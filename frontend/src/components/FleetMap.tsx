/**
 * The fleet map's parts: machines (status colour, heading), their names as labels, live
 * trails, and the coverage of running jobs painted as records arrive.
 *
 * Labels are DOM markers, not a symbol layer: the offline base style has no glyph server.
 * Coverage is the job's own as-applied cell tiles (the report's figures: a cell is painted
 * once something landed in it), reloaded at most every `COVERAGE_REFRESH_MS` while the
 * job's progress messages come in.
 */
import { useEffect, useRef, useState } from 'react';
import * as maplibregl from 'maplibre-gl';
import { call, client } from '../api/client';
import { statusColor } from '../lib/colors';
import type { Fleet } from '../lib/fleet';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { MapView } from '../map/MapView';
import { absoluteApiUrl, fitTo, setGeoJSON } from '../map/setup';

export const COVERAGE_REFRESH_MS = 2000;

function machinesFC(fleet: Fleet): GeoJSON.FeatureCollection {
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

function trailsFC(trails: Map<number, [number, number][]>): GeoJSON.FeatureCollection {
  return {
    type: 'FeatureCollection',
    features: [...trails.entries()]
      .filter(([, c]) => c.length > 1)
      .map(([id, c]) => ({ type: 'Feature', properties: { machine_id: id }, geometry: { type: 'LineString', coordinates: c } })),
  };
}

function addBaseLayers(map: maplibregl.Map, fleet: Fleet): void {
  setGeoJSON(map, 'fields', { type: 'FeatureCollection', features: [] });
  map.addLayer({ id: 'fields-fill', type: 'fill', source: 'fields', paint: { 'fill-color': '#4c9a2a', 'fill-opacity': 0.15 } });
  map.addLayer({ id: 'fields-line', type: 'line', source: 'fields', paint: { 'line-color': '#2d5e16', 'line-width': 1 } });
  call(client.GET('/api/v1/fields', { params: { query: { limit: 500 } } }))
    .then((fc) => setGeoJSON(map, 'fields', asGeoJSON(fc)))
    .catch(() => undefined);
  setGeoJSON(map, 'trails', { type: 'FeatureCollection', features: [] });
  map.addLayer({ id: 'trails', type: 'line', source: 'trails', paint: { 'line-color': '#1e3a8a', 'line-width': 2, 'line-opacity': 0.6 } });
  setGeoJSON(map, 'machines', machinesFC(fleet));
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
}

/** One DOM label per machine with a position, kept in step with the fleet. */
function useMachineLabels(map: maplibregl.Map | null, fleet: Fleet): void {
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
}

function coverageUrl(jobId: number, v: number): string {
  return absoluteApiUrl(`/api/v1/tiles/jobs/${jobId}/{z}/{x}/{y}.mvt?v=${v}`);
}

/**
 * The running jobs' covered cells, under the trails and machines. A job's tiles reload when
 * its progress has moved, checked every COVERAGE_REFRESH_MS (not on every message: a busy
 * job sends several a second and each reload re-reads the report's cells).
 */
function useLiveCoverage(map: maplibregl.Map | null, fleet: Fleet): void {
  const shown = useRef(new Map<number, number>()); // job id -> progress its tiles show
  const latest = useRef(new Map<number, number>()); // job id -> progress now
  useEffect(() => {
    if (!map) return;
    const running = new Map<number, number>();
    for (const m of fleet.values()) if (m.job_id != null && m.job_state === 'running') running.set(m.job_id, m.progress ?? 0);
    latest.current = running;
    for (const [jobId, progress] of running) {
      const src = `coverage-${jobId}`;
      if (map.getSource(src)) continue;
      map.addSource(src, { type: 'vector', tiles: [coverageUrl(jobId, Date.now())], minzoom: 10, maxzoom: 20 });
      map.addLayer(
        {
          id: src,
          type: 'fill',
          source: src,
          'source-layer': 'cells',
          filter: ['>', ['to-number', ['get', 'n_records'], 0], 0],
          paint: { 'fill-color': '#f0b400', 'fill-opacity': 0.55 },
        },
        map.getLayer('trails') ? 'trails' : undefined,
      );
      shown.current.set(jobId, progress);
    }
    for (const jobId of [...shown.current.keys()])
      if (!running.has(jobId)) {
        // ended: the job report shows the result; the fleet map shows work in progress
        const src = `coverage-${jobId}`;
        if (map.getLayer(src)) map.removeLayer(src);
        if (map.getSource(src)) map.removeSource(src);
        shown.current.delete(jobId);
      }
  }, [map, fleet]);
  useEffect(() => {
    if (!map) return;
    const t = setInterval(() => {
      for (const [jobId, progress] of latest.current) {
        const src = map.getSource(`coverage-${jobId}`) as maplibregl.VectorTileSource | undefined;
        if (!src || shown.current.get(jobId) === progress) continue;
        src.setTiles([coverageUrl(jobId, Date.now())]);
        shown.current.set(jobId, progress);
      }
    }, COVERAGE_REFRESH_MS);
    return () => clearInterval(t);
  }, [map]);
}

/** The fleet's map: fitted once to the machines, then left where the user puts it. */
export function FleetMap(props: { fleet: Fleet; trails: Map<number, [number, number][]> }) {
  const { fleet, trails } = props;
  const fitted = useRef(false);
  const fleetRef = useRef(fleet);
  fleetRef.current = fleet;
  const [map, setMap] = useState<maplibregl.Map | null>(null);

  useEffect(() => {
    if (!map) return;
    const fc = machinesFC(fleet);
    setGeoJSON(map, 'machines', fc);
    setGeoJSON(map, 'trails', trailsFC(trails));
    if (!fitted.current && fc.features.length) {
      const c = map.getContainer();
      fitTo(map, bboxOf(fc), Math.min(200, c.clientWidth / 5, c.clientHeight / 5));
      if (map.getZoom() > 16) map.setZoom(16);
      fitted.current = true;
    }
  }, [map, fleet, trails]);
  useMachineLabels(map, fleet);
  useLiveCoverage(map, fleet);

  return (
    <MapView
      name="fleet"
      onReady={(m) => {
        addBaseLayers(m, fleetRef.current);
        setMap(m);
      }}
    />
  );
}
