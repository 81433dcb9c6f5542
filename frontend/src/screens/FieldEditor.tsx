import { useEffect, useRef, useState } from 'react';
import type { TerraDraw } from 'terra-draw';
import { ApiError, call, client } from '../api/client';
import { qk, useApiMutation, useFarms, useField } from '../api/hooks';
import { ErrorBox } from '../components/Status';
import {
  bboxOf,
  geodesicAreaM2,
  selfIntersection,
  withHoles,
  type AreaGeom,
  type PolygonGeom,
  type Ring,
} from '../lib/geo';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { peek, undoKey, useUndoable } from '../lib/history';
import { FitBounds, Holes, Problems, ZoneDraw } from '../map/overlays';
import { navigate } from '../router';

type Mode = 'polygon' | 'hole' | 'select';

/** What undo/redo steps through: the outer ring being drawn, its holes, and untouched extra parts. */
interface Shape {
  outer: Ring | null;
  holes: Ring[];
  /** Further polygons of a multi-part field (kept as loaded). */
  extra: Ring[][];
}
const BLANK: Shape = { outer: null, holes: [], extra: [] };

/** Draw a new field (fieldId undefined) or edit an existing one's vertices and holes; undo/redo every step. */
export function FieldEditor({ fieldId }: { fieldId?: number }) {
  const [form, setForm] = useState<{ name: string; farmId: string | null; crop: string }>({ name: '', farmId: null, crop: '' });
  const [mode, setMode] = useState<Mode>('polygon');
  const shape = useUndoable<Shape>(BLANK);
  const farmsQ = useFarms();
  const farms = farmsQ.data?.items ?? [];
  const fieldQ = useField(fieldId);
  const drawRef = useRef<TerraDraw | null>(null);
  const modeRef = useRef<Mode>('polygon');
  modeRef.current = mode;
  // The finished outer ring's terra-draw id; hole sketches never count as the boundary.
  const outerIdRef = useRef<string | number | null>(null);
  // Set while undo/redo/load rewrite the drawing: its change events are not user steps.
  const applying = useRef(false);
  const { outer: outerRing, holes, extra } = shape.present;
  const outer: PolygonGeom | null = outerRing ? { type: 'Polygon', coordinates: [outerRing] } : null;
  const presentRef = useRef(shape.present);
  presentRef.current = shape.present;

  // a new field starts on the first farm until the user picks one ('' = no farm, kept)
  const farmId = form.farmId ?? (fieldId || !farms[0] ? '' : String(farms[0].id));

  const save = useApiMutation(
    async (geometry: AreaGeom) => {
      const properties = { name: form.name, farm_id: farmId ? Number(farmId) : null, crop: form.crop };
      return fieldId
        ? call(client.PATCH('/api/v1/fields/{field_id}', { params: { path: { field_id: fieldId } }, body: { geometry: { ...geometry }, properties } }))
        : call(client.POST('/api/v1/fields', { body: { type: 'Feature', geometry: { ...geometry }, properties } }));
    },
    { invalidate: (r) => [qk.fields(), qk.field(r.id)] },
  );
  const error = save.error ?? fieldQ.error ?? farmsQ.error;

  const geometry: AreaGeom | null = outer
    ? extra.length
      ? { type: 'MultiPolygon', coordinates: [withHoles(outer, holes).coordinates, ...extra] }
      : withHoles(outer, holes)
    : null;
  const area = geodesicAreaM2(geometry);
  const crossing = outer ? selfIntersection(outer.coordinates[0]) : null;
  const serverLoc = save.error instanceof ApiError ? save.error.parsed.location : undefined;

  /** The outer ring as terra-draw has it now (null while nothing is drawn). */
  const drawnOuter = (): Ring | null | undefined => {
    const draw = drawRef.current;
    if (!draw) return undefined;
    const snap = draw.getSnapshot().filter((f) => f.geometry.type === 'Polygon');
    let f = outerIdRef.current != null ? snap.find((x) => x.id === outerIdRef.current) : undefined;
    // While the first boundary is being drawn, show its area live.
    if (!f && outerIdRef.current == null && modeRef.current !== 'hole') f = snap[snap.length - 1];
    if (modeRef.current === 'hole' && !f) return undefined;
    return f ? (f.geometry.coordinates as Ring[])[0] : null;
  };

  /** Put `s` on the drawing tool (undo/redo/load): one polygon, selected for editing. */
  const toDraw = (s: Shape) => {
    const draw = drawRef.current;
    if (!draw) return;
    applying.current = true;
    try {
      draw.clear();
      outerIdRef.current = null;
      if (s.outer) {
        const [added] = draw.addFeatures([
          { type: 'Feature', geometry: { type: 'Polygon', coordinates: [s.outer] }, properties: { mode: 'polygon' } },
        ]);
        if (added?.valid) outerIdRef.current = added.id ?? null;
        draw.setMode('select');
        setMode('select');
        if (outerIdRef.current != null) draw.selectFeature(outerIdRef.current);
      } else {
        draw.setMode('polygon');
        setMode('polygon');
      }
    } finally {
      applying.current = false;
    }
  };

  const step = (dir: 'undo' | 'redo') => {
    const target = peek(shape.history, dir);
    if (!target) return;
    toDraw(target);
    if (dir === 'undo') shape.undo();
    else shape.redo();
  };
  const stepRef = useRef(step);
  stepRef.current = step;
  useEffect(() => {
    const onKey = (e: KeyboardEvent) => {
      const dir = undoKey(e, e.target);
      if (!dir) return;
      e.preventDefault();
      stepRef.current(dir);
    };
    window.addEventListener('keydown', onKey);
    return () => window.removeEventListener('keydown', onKey);
  }, []);

  // An existing field: its boundary on the drawing tool once both are there (once).
  const loaded = useRef(false);
  const loadField = () => {
    const field = fieldQ.data;
    if (loaded.current || !field || !drawRef.current) return;
    loaded.current = true;
    const g = field.geometry as unknown as AreaGeom;
    setForm({
      name: field.properties.name ?? '',
      crop: field.properties.crop ?? '',
      farmId: field.properties.farm_id != null ? String(field.properties.farm_id) : '',
    });
    const parts: Ring[][] = g.type === 'Polygon' ? [g.coordinates] : g.coordinates;
    const [first, ...rest] = parts;
    const s: Shape = { outer: first[0], holes: first.slice(1), extra: rest };
    shape.reset(s);
    toDraw(s);
  };
  const loadRef = useRef(loadField);
  loadRef.current = loadField;
  useEffect(() => loadRef.current(), [fieldQ.data]);

  const onFinish = (id: string | number, draw: TerraDraw, ctx: { action: string }) => {
    const f = draw.getSnapshotFeature(id);
    if (!f || f.geometry.type !== 'Polygon') return;
    const cur = presentRef.current;
    if (modeRef.current === 'hole') {
      const ring = (f.geometry.coordinates as Ring[])[0];
      draw.removeFeatures([id]);
      shape.commit({ ...cur, holes: [...cur.holes, ring] });
      return;
    }
    if (ctx.action === 'draw') {
      // One outer ring at a time: a new polygon replaces the previous one.
      outerIdRef.current = id;
      save.reset(); // a new boundary: the old server verdict no longer applies
      const others = draw
        .getSnapshot()
        .filter((x) => x.id !== id)
        .map((x) => x.id as string);
      if (others.length) draw.removeFeatures(others);
      setMode('select');
      draw.setMode('select');
      draw.selectFeature(id);
    }
    const ring = drawnOuter();
    if (ring !== undefined) shape.commit({ ...cur, outer: ring });
  };

  const onChange = () => {
    if (applying.current) return;
    const ring = drawnOuter();
    if (ring !== undefined) shape.replace({ ...presentRef.current, outer: ring });
  };

  const switchMode = (m: Mode) => {
    setMode(m);
    drawRef.current?.setMode(m === 'hole' ? 'polygon' : m);
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
                <button
                  className="link"
                  onClick={() => shape.commit({ ...shape.present, holes: holes.filter((_, j) => j !== i) })}
                >
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
          <input data-testid="field-name" value={form.name} onChange={(e) => setForm({ ...form, name: e.target.value })} />
        </label>
        <label>
          Farm
          <select data-testid="field-farm" value={farmId} onChange={(e) => setForm({ ...form, farmId: e.target.value })}>
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
          <input data-testid="field-crop" value={form.crop} onChange={(e) => setForm({ ...form, crop: e.target.value })} />
        </label>
        <div className="row">
          <button
            data-testid="field-save"
            data-write=""
            disabled={!geometry || !form.name || save.isPending}
            onClick={() => geometry && save.mutate(geometry, { onSuccess: (r) => navigate(`/fields/${r.id}`) })}
          >
            Save field
          </button>
          <button
            className="secondary"
            data-testid="draw-clear"
            onClick={() => {
              save.reset();
              const s = { ...BLANK, extra };
              toDraw(s);
              shape.commit(s);
            }}
          >
            Clear
          </button>
        </div>
        <div className="row" role="group" aria-label="History">
          <button
            className="secondary"
            data-testid="draw-undo"
            disabled={!shape.canUndo}
            title="Undo (Ctrl+Z)"
            onClick={() => step('undo')}
          >
            Undo
          </button>
          <button
            className="secondary"
            data-testid="draw-redo"
            disabled={!shape.canRedo}
            title="Redo (Ctrl+Shift+Z)"
            onClick={() => step('redo')}
          >
            Redo
          </button>
        </div>
        <ErrorBox error={error} testid="field-error" />
      </aside>
      <MapView name="draw" fieldId={fieldId}>
        <Holes rings={holes} />
        <ZoneDraw
          mode={mode === 'hole' ? 'polygon' : mode}
          editable
          onReady={(draw) => {
            drawRef.current = draw;
            loadRef.current();
          }}
          onChange={onChange}
          onFinish={onFinish}
        />
        {/* the server's location wins, else our own self-intersection check; above the drawing */}
        <Problems points={serverLoc ? [serverLoc] : [crossing]} />
        {fieldQ.data && <FitBounds bbox={bboxOf(fieldQ.data)} once />}
      </MapView>
    </div>
  );
}
