import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { TerraDraw, TerraDrawPolygonMode, TerraDrawSelectMode } from 'terra-draw';
import { TerraDrawMapLibreGLAdapter } from 'terra-draw-maplibre-gl-adapter';
import { ApiError, call, client, type Farm } from '../api/client';
import { ErrorBox } from '../components/Status';
import {
  bboxOf,
  closeRing,
  geodesicAreaM2,
  selfIntersection,
  withHoles,
  type AreaGeom,
  type PolygonGeom,
  type Ring,
} from '../lib/geo';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import { navigate } from '../router';

type Mode = 'polygon' | 'hole' | 'select';

declare global {
  interface Window {
    __fieldrxDraw?: TerraDraw;
  }
}

/** Draw a new field (fieldId undefined) or edit an existing one's vertices and holes. */
export function FieldEditor({ fieldId }: { fieldId?: number }) {
  const [farms, setFarms] = useState<Farm[]>([]);
  const [name, setName] = useState('');
  const [farmId, setFarmId] = useState('');
  const [crop, setCrop] = useState('');
  const [mode, setMode] = useState<Mode>('polygon');
  const [outer, setOuter] = useState<PolygonGeom | null>(null);
  const [holes, setHoles] = useState<Ring[]>([]);
  const [extraParts, setExtraParts] = useState<Ring[][]>([]);
  const [error, setError] = useState<unknown>(null);
  const [busy, setBusy] = useState(false);
  const drawRef = useRef<TerraDraw | null>(null);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const modeRef = useRef<Mode>('polygon');
  modeRef.current = mode;

  useEffect(() => {
    call(client.GET('/api/v1/farms'))
      .then((r) => {
        const fs = r.items;
        setFarms(fs);
        setFarmId((cur) => cur || (fs[0] ? String(fs[0].id) : ''));
      })
      .catch(setError);
  }, []);

  const geometry: AreaGeom | null = outer
    ? extraParts.length
      ? { type: 'MultiPolygon', coordinates: [withHoles(outer, holes).coordinates, ...extraParts] }
      : withHoles(outer, holes)
    : null;
  const area = geodesicAreaM2(geometry);
  const crossing = outer ? selfIntersection(outer.coordinates[0]) : null;
  const serverLoc = error instanceof ApiError ? error.parsed.location : undefined;

  // Problem markers: the server's location wins, else our own self-intersection check.
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    const pts: GeoJSON.Feature[] = [];
    if (serverLoc)
      pts.push({ type: 'Feature', properties: { kind: 'server' }, geometry: { type: 'Point', coordinates: serverLoc } });
    if (crossing)
      pts.push({ type: 'Feature', properties: { kind: 'local' }, geometry: { type: 'Point', coordinates: crossing } });
    setGeoJSON(map, 'problems', { type: 'FeatureCollection', features: pts });
    if (map.getLayer('problems')) map.moveLayer('problems'); // above terra-draw's layers
    setGeoJSON(map, 'holes', {
      type: 'FeatureCollection',
      features: holes.map((h) => ({
        type: 'Feature',
        properties: {},
        geometry: { type: 'Polygon', coordinates: [closeRing(h)] },
      })),
    });
  }, [serverLoc?.[0], serverLoc?.[1], crossing?.[0], crossing?.[1], holes]);

  // The finished outer ring's terra-draw id; hole sketches never count as the boundary.
  const outerIdRef = useRef<string | number | null>(null);
  const syncOuter = () => {
    const draw = drawRef.current;
    if (!draw) return;
    const snap = draw.getSnapshot().filter((f) => f.geometry.type === 'Polygon');
    let f = outerIdRef.current != null ? snap.find((x) => x.id === outerIdRef.current) : undefined;
    // While the first boundary is being drawn, show its area live.
    if (!f && outerIdRef.current == null && modeRef.current !== 'hole') f = snap[snap.length - 1];
    if (modeRef.current === 'hole' && !f) return;
    setOuter(f ? ({ type: 'Polygon', coordinates: f.geometry.coordinates } as PolygonGeom) : null);
  };

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'holes', { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'holes-fill', type: 'fill', source: 'holes', paint: { 'fill-color': '#ffffff', 'fill-opacity': 0.7 } });
    map.addLayer({
      id: 'holes-line',
      type: 'line',
      source: 'holes',
      paint: { 'line-color': '#b00020', 'line-width': 2, 'line-dasharray': [2, 1] },
    });
    setGeoJSON(map, 'problems', { type: 'FeatureCollection', features: [] });
    map.addLayer({
      id: 'problems',
      type: 'circle',
      source: 'problems',
      paint: {
        'circle-radius': 14,
        'circle-color': 'rgba(215, 38, 61, 0.35)',
        'circle-stroke-color': '#d7263d',
        'circle-stroke-width': 3,
      },
    });
    const draw = new TerraDraw({
      adapter: new TerraDrawMapLibreGLAdapter({ map }),
      modes: [
        new TerraDrawPolygonMode(),
        new TerraDrawSelectMode({
          flags: {
            polygon: {
              feature: {
                draggable: true,
                coordinates: { midpoints: true, draggable: true, deletable: true },
              },
            },
          },
        }),
      ],
    });
    draw.start();
    draw.setMode('polygon');
    drawRef.current = draw;
    window.__fieldrxDraw = draw;
    draw.on('change', () => syncOuter());
    draw.on('finish', (id) => {
      const f = draw.getSnapshotFeature(id);
      if (!f || f.geometry.type !== 'Polygon') return;
      if (modeRef.current === 'hole') {
        const ring = (f.geometry.coordinates as Ring[])[0];
        draw.removeFeatures([id]);
        setHoles((h) => [...h, ring]);
        return;
      }
      // One outer ring at a time: a new polygon replaces the previous one.
      outerIdRef.current = id;
      setError(null); // a new boundary: the old server verdict no longer applies
      const others = draw
        .getSnapshot()
        .filter((x) => x.id !== id)
        .map((x) => x.id as string);
      if (others.length) draw.removeFeatures(others);
      syncOuter();
      setMode('select');
      draw.setMode('select');
      draw.selectFeature(id);
    });

    if (fieldId) {
      call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: fieldId } } }))
        .then((field) => {
          const f = { ...field, geometry: field.geometry as unknown as AreaGeom };
          setName(f.properties.name ?? '');
          setCrop(f.properties.crop ?? '');
          if (f.properties.farm_id != null) setFarmId(String(f.properties.farm_id));
          const parts: Ring[][] =
            f.geometry.type === 'Polygon' ? [f.geometry.coordinates] : f.geometry.coordinates;
          const [first, ...rest] = parts;
          setExtraParts(rest);
          setHoles(first.slice(1));
          const [added] = draw.addFeatures([
            {
              type: 'Feature',
              geometry: { type: 'Polygon', coordinates: [first[0]] },
              properties: { mode: 'polygon' },
            },
          ]);
          if (added?.valid) outerIdRef.current = added.id ?? null;
          syncOuter();
          draw.setMode('select');
          setMode('select');
          fitTo(map, bboxOf(f));
        })
        .catch(setError);
    } else {
      // Start where the organisation's fields are, not on a world view.
      call(client.GET('/api/v1/fields', { params: { query: { limit: 500 } } }))
        .then((fc) => fitTo(map, bboxOf(fc), 80))
        .catch(() => undefined);
    }
    return () => {
      window.__fieldrxDraw = undefined;
      try {
        draw.stop();
      } catch {
        /* map already gone */
      }
    };
  };

  const switchMode = (m: Mode) => {
    setMode(m);
    drawRef.current?.setMode(m === 'hole' ? 'polygon' : m);
  };

  const save = async () => {
    if (!geometry) return;
    setBusy(true);
    setError(null);
    const properties = { name, farm_id: farmId ? Number(farmId) : null, crop };
    try {
      const r = fieldId
        ? await call(client.PATCH('/api/v1/fields/{field_id}', { params: { path: { field_id: fieldId } }, body: { geometry: { ...geometry }, properties } }))
        : await call(client.POST('/api/v1/fields', { body: { type: 'Feature', geometry: { ...geometry }, properties } }));
      navigate(`/fields/${r.id}`);
    } catch (e) {
      setError(e);
    } finally {
      setBusy(false);
    }
  };

  return (
    <div className="split">
      <aside className="panel">
        <h2>{fieldId ? 'Edit field' : 'New field'}</h2>
        <p className="muted">
          Click on the map to add corners; click the first corner to close. Then drag corners to edit, or cut holes.
        </p>
        <div className="row" role="group">
          <button
            data-testid="mode-polygon"
            className={mode === 'polygon' ? 'on' : ''}
            onClick={() => switchMode('polygon')}
          >
            Draw boundary
          </button>
          <button data-testid="mode-select" className={mode === 'select' ? 'on' : ''} onClick={() => switchMode('select')}>
            Edit vertices
          </button>
          <button
            data-testid="mode-hole"
            className={mode === 'hole' ? 'on' : ''}
            disabled={!outer}
            onClick={() => switchMode('hole')}
          >
            Cut hole
          </button>
        </div>
        <p>
          Area: <strong data-testid="draw-area">{formatArea(area)}</strong>
          {holes.length > 0 && (
            <span className="muted" data-testid="hole-count">
              {' '}
              ({holes.length} hole{holes.length === 1 ? '' : 's'})
            </span>
          )}
        </p>
        {holes.length > 0 && (
          <ul className="list">
            {holes.map((_, i) => (
              <li key={i}>
                Hole {i + 1}{' '}
                <button className="link" onClick={() => setHoles((h) => h.filter((_, j) => j !== i))}>
                  remove
                </button>
              </li>
            ))}
          </ul>
        )}
        {crossing && (
          <p className="warn" data-testid="draw-warning">
            The boundary crosses itself (marked in red).
          </p>
        )}
        <label>
          Name
          <input data-testid="field-name" value={name} onChange={(e) => setName(e.target.value)} />
        </label>
        <label>
          Farm
          <select data-testid="field-farm" value={farmId} onChange={(e) => setFarmId(e.target.value)}>
            <option value="">—</option>
            {farms.map((f) => (
              <option key={f.id} value={f.id}>
                {f.name}
              </option>
            ))}
          </select>
        </label>
        <label>
          Crop
          <input data-testid="field-crop" value={crop} onChange={(e) => setCrop(e.target.value)} />
        </label>
        <div className="row">
          <button data-testid="field-save" data-write="" disabled={!geometry || !name || busy} onClick={() => void save()}>
            Save field
          </button>
          <button
            className="secondary"
            data-testid="draw-clear"
            onClick={() => {
              drawRef.current?.clear();
              outerIdRef.current = null;
              setError(null);
              setHoles([]);
              setOuter(null);
              switchMode('polygon');
            }}
          >
            Clear
          </button>
        </div>
        <ErrorBox error={error} testid="field-error" />
      </aside>
      <MapView name="draw" onReady={onReady} fieldId={fieldId} />
    </div>
  );
}
