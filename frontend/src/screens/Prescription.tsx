import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { TerraDraw, TerraDrawPolygonMode } from 'terra-draw';
import { TerraDrawMapLibreGLAdapter } from 'terra-draw-maplibre-gl-adapter';
import {
  ApiError,
  call,
  client,
  download,
  type FieldFeature,
  type Machine,
  type Prescription,
  type Schemas,
} from '../api/client';
import { Histogram, Legend } from '../components/Legend';
import { ErrorBox, Kv } from '../components/Status';
import { classColors, classify, histogram, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { attentionLines, attentionOf, attentionSummary, flaggedConfirmation } from '../lib/flags';
import { asGeoJSON, bboxOf, type PolygonGeom } from '../lib/geo';
import { formatRate } from '../lib/units';
import { MapView } from '../map/MapView';
import { loadedCells, replaceVectorSource, rxGridLayers, rxTilesUrl } from '../map/grid';
import { fitTo, setGeoJSON } from '../map/setup';
import { navigate } from '../router';

const CLASSES = 6;
const EXPORTS: [string, string, string][] = [
  ['geojson', 'GeoJSON', 'geojson'],
  ['csv', 'CSV', 'csv'],
  ['shapefile', 'Shapefile', 'zip'],
  ['isoxml', 'ISOXML', 'zip'],
  // terminal layouts: rate zones within the terminal's polygon limit (the server says what it merged)
  ['isoxml-zones', 'ISOXML zones', 'zip'],
  ['shapefile&profile=deere', 'John Deere (Rx/)', 'zip'],
  ['shapefile&profile=fieldview', 'FieldView', 'zip'],
  ['shapefile&profile=raven', 'Raven / Ag Leader / Trimble', 'zip'],
];

interface CellInfo {
  seq: number;
  rate: number;
  flags?: string;
  clamped?: boolean;
  /** >1 on overview tiles (cells binned when narrower than ~2 px). */
  nCells: number;
}

/** Versioned rate map: colour grid + legend + histogram, cell and zone edits, exports, send to a machine. */
export function PrescriptionScreen({ rxId }: { rxId: number }) {
  const [rx, setRx] = useState<Prescription | null>(null);
  const [version, setVersion] = useState<number | null>(null);
  const [field, setField] = useState<FieldFeature | null>(null);
  const [rates, setRates] = useState<number[]>([]);
  const [cell, setCell] = useState<CellInfo | null>(null);
  const [newRate, setNewRate] = useState('');
  const [zone, setZone] = useState<PolygonGeom | null>(null);
  const [zoneRate, setZoneRate] = useState('');
  const [painting, setPainting] = useState(false);
  const [machines, setMachines] = useState<Machine[]>([]);
  const [machineId, setMachineId] = useState('');
  const [msg, setMsg] = useState('');
  const [verSummary, setVerSummary] = useState<Schemas['RxSummary'] | null>(null);
  const [confirmJob, setConfirmJob] = useState<{ message: string; count: number; areaM2: number; seq: number[] } | null>(null);
  const [error, setError] = useState<unknown>(null);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const drawRef = useRef<TerraDraw | null>(null);
  const [mapReady, setMapReady] = useState(false);
  // Tiles are requested only once the map is fitted to the field (no wasted low-zoom requests).
  const [fitted, setFitted] = useState(false);

  const load = useCallback(
    async (pickVersion?: number) => {
      try {
        const r = await call(client.GET('/api/v1/prescriptions/{rx_id}', { params: { path: { rx_id: rxId } } }));
        setRx(r);
        setVersion(pickVersion ?? r.current_version);
        if (!field) {
          try {
            const plan = await call(client.GET('/api/v1/plans/{plan_id}', { params: { path: { plan_id: r.plan_id } } }));
            setField(await call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: plan.field_id } } })));
          } catch {
            setFitted(true); // no boundary to fit to: show the grid wherever the map is
          }
        }
      } catch (e) {
        setError(e);
      }
    },
    [rxId, field],
  );

  useEffect(() => {
    void load();
    call(client.GET('/api/v1/machines'))
      .then((m) => {
        const ms = m.items;
        setMachines(ms);
        if (ms[0]) setMachineId(String(ms[0].id));
      })
      .catch(() => undefined);
    // eslint-disable-next-line react-hooks/exhaustive-deps
  }, [rxId]);

  useEffect(() => {
    const current = rx?.current_version;
    if (!rx || version == null || version === current) {
      setVerSummary(null);
      return;
    }
    let live = true;
    call(client.GET('/api/v1/prescriptions/{rx_id}/versions/{version}', { params: { path: { rx_id: rxId, version } } }))
      .then((v) => live && setVerSummary(v.summary))
      .catch(() => live && setVerSummary(null));
    return () => {
      live = false;
    };
  }, [rx, version, rxId]);

  // The summary of the version on screen: the prescription's own is its current version's,
  // another version's is fetched (figures, flags, legend and histogram all follow the choice).
  const shown = verSummary ?? rx?.summary;
  const attention = attentionOf(verSummary ? { ...rx, summary: verSummary } : rx);
  // The server's summary covers every cell; loaded tiles are the fallback.
  const lo = shown?.rate_min_kg_ha ?? (rates.length ? minOf(rates) : undefined);
  const hi = shown?.rate_max_kg_ha ?? (rates.length ? maxOf(rates) : undefined);
  const breaks = useMemo(() => niceBreaks(lo ?? 0, hi ?? 1000, CLASSES), [lo, hi]);
  const colors = useMemo(() => classColors(breaks.length - 1), [breaks]);
  const legend =
    lo != null && lo === hi
      ? [{ color: colors[0], from: lo, to: lo, label: `${lo.toFixed(1)} (uniform)` }]
      : legendEntries(breaks, colors, (v) => v.toFixed(0));
  const colorExpr = useMemo(() => stepExpression('rate_kg_ha', breaks, colors), [breaks, colors]);
  // Whole-field, area-weighted histogram of the version on screen, from the server's summary
  // (never from the tiles on screen: those change with zoom and bin overview cells); each
  // bar takes the legend colour of its middle rate.
  const serverHist = useMemo(() => {
    const h = shown?.histogram;
    if (!h || !h.area_m2.length) return null;
    const mids = h.edges_kg_ha.slice(0, -1).map((e, i) => (e + h.edges_kg_ha[i + 1]) / 2);
    return {
      counts: h.area_m2.map((a) => Math.round(a / 100) / 100),
      colors: mids.map((m) => colors[classify(m, breaks)]),
      labels: h.edges_kg_ha.slice(0, -1).map((e, i) => `${e.toFixed(0)}–${h.edges_kg_ha[i + 1].toFixed(0)} kg/ha`),
    };
  }, [shown, breaks, colors]);

  // (Re)load the tile source for the chosen version.
  useEffect(() => {
    const map = mapRef.current;
    if (!map || !mapReady || !fitted || version == null) return;
    replaceVectorSource(map, 'rx', rxTilesUrl(rxId, version), rxGridLayers('rx', colorExpr));
    setRates([]);
    const onIdle = () => {
      const cells = loadedCells(map, 'rx');
      if (!cells.size) return;
      const vals: number[] = [];
      for (const p of cells.values()) {
        // Overview tiles bin many cells into one feature: weight by n_cells.
        const n = Math.max(1, Number(p.n_cells ?? 1) || 1);
        const r = Number(p.rate_kg_ha);
        for (let i = 0; i < n; i++) vals.push(r);
      }
      setRates(vals);
      map.off('idle', onIdle);
    };
    map.on('idle', onIdle);
    return () => {
      map.off('idle', onIdle);
    };
  }, [mapReady, fitted, version, rxId]); // eslint-disable-line react-hooks/exhaustive-deps

  useEffect(() => {
    const map = mapRef.current;
    if (map?.getLayer('rx-fill')) map.setPaintProperty('rx-fill', 'fill-color', colorExpr as never);
  }, [colorExpr]);

  useEffect(() => {
    const map = mapRef.current;
    if (map?.getLayer('rx-selected')) map.setFilter('rx-selected', ['==', ['get', 'seq'], cell?.seq ?? -1]);
  }, [cell]);

  useEffect(() => {
    const map = mapRef.current;
    if (!map || !field) return;
    setGeoJSON(map, 'field', asGeoJSON(field));
    fitTo(map, bboxOf(field));
    setFitted(true);
  }, [field, mapReady]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#222', 'line-width': 2 } });
    map.on('click', (e) => {
      if (drawRef.current?.getMode() === 'polygon') return;
      if (!map.getLayer('rx-fill')) return;
      const f = map.queryRenderedFeatures(e.point, { layers: ['rx-fill'] })[0];
      if (!f) return setCell(null);
      const c: CellInfo = {
        seq: Number(f.properties.seq),
        rate: Number(f.properties.rate_kg_ha),
        flags: (f.properties.flags as string) || '',
        clamped: f.properties.clamped === true,
        nCells: Number(f.properties.n_cells ?? 1) || 1,
      };
      setCell(c);
      setNewRate(String(Math.round(c.rate * 10) / 10));
    });
    const draw = new TerraDraw({ adapter: new TerraDrawMapLibreGLAdapter({ map }), modes: [new TerraDrawPolygonMode()] });
    draw.start();
    draw.setMode('static');
    draw.on('finish', (id) => {
      const f = draw.getSnapshotFeature(id);
      if (f?.geometry.type === 'Polygon') setZone(f.geometry as PolygonGeom);
      draw.setMode('static');
      setPainting(false);
    });
    drawRef.current = draw;
    setMapReady(true);
    return () => {
      try {
        draw.stop();
      } catch {
        /* map gone */
      }
    };
  };

  const applyEdit = async (body: Schemas['EditIn']) => {
    setError(null);
    try {
      const r = await call(client.POST('/api/v1/prescriptions/{rx_id}/edits', { params: { path: { rx_id: rxId } }, body }));
      const v = r.new_version;
      setCell(null);
      setZone(null);
      drawRef.current?.clear();
      await load(v);
      setMsg(`Saved as version ${v}`);
    } catch (e) {
      setError(e);
    }
  };

  /** Creates the job; a 409 naming flagged cells asks the user to confirm, then resends with the flag. */
  const sendJob = async (confirmFlagged: boolean) => {
    setError(null);
    try {
      const j = await call(
        client.POST('/api/v1/jobs', {
          body: {
            prescription_id: rxId,
            prescription_version: version ?? undefined,
            machine_id: Number(machineId),
            confirm_flagged: confirmFlagged,
          },
        }),
      );
      setConfirmJob(null);
      // A new job is 'planned'; sending makes it downloadable by the machine.
      if (j.state === 'planned')
        await call(client.POST('/api/v1/jobs/{job_id}/state', { params: { path: { job_id: j.id } }, body: { state: 'sent' } }));
      setMsg(`Job #${j.id} created`);
      navigate(`/jobs?created=${j.id}`);
    } catch (e) {
      const c = e instanceof ApiError ? flaggedConfirmation(e.status, e.body) : null;
      if (c) setConfirmJob(c);
      else setError(e);
    }
  };

  const versions = rx?.versions ?? [];
  const versionNums = versions.map((v) => v.version);

  return (
    <div className="split">
      <aside className="panel">
        <p>{rx && <a href={`#/plans/${rx.plan_id}`}>← Plan #{rx.plan_id}</a>}</p>
        <h2>Prescription #{rxId}</h2>
        <ErrorBox error={error} testid="rx-screen-error" />
        {msg && (
          <p className="ok" data-testid="rx-msg">
            {msg}
          </p>
        )}
        <Kv
          items={[
            ['Model', String(rx?.model ?? '–'), 'rx-model-name'],
            ['Cells', String(shown?.n_cells ?? (rates.length || '–')), 'rx-cell-count'],
            ['Rate range', lo != null && hi != null ? `${formatRate(lo)} – ${formatRate(hi)}` : '–', 'rx-range'],
            ['Flagged cells', rx ? attentionSummary(attention) : '–', 'rx-flagged'],
          ]}
        />
        {attention.count > 0 && (
          <div className="card warn" data-testid="rx-flagged-detail">
            <div>
              <strong>{attentionSummary(attention)}</strong> will not be applied as prescribed:
            </div>
            <ul>
              {attentionLines(attention).map((l) => (
                <li key={l}>{l}</li>
              ))}
            </ul>
            <div className="small">
              Rates are stored as asked (outlined on the map). Cells:{' '}
              <span data-testid="rx-flagged-seq">
                {attention.seq.slice(0, 30).join(', ')}
                {attention.count > 30 ? ` … (${attention.count - 30} more)` : ''}
              </span>
            </div>
          </div>
        )}
        <label>
          Version
          <select
            data-testid="rx-version"
            value={version ?? ''}
            onChange={(e) => setVersion(Number(e.target.value))}
          >
            {versionNums.map((v) => (
              <option key={v} value={v}>
                v{v}
              </option>
            ))}
          </select>
        </label>
        <Legend entries={legend} title="Rate (kg/ha)" testid="rx-legend" />
        {serverHist ? (
          <Histogram
            counts={serverHist.counts}
            colors={serverHist.colors}
            unit="ha"
            labels={serverHist.labels}
            testid="rx-histogram"
          />
        ) : (
          <Histogram counts={histogram(rates, breaks)} colors={colors} testid="rx-histogram" />
        )}

        <h3>Edit</h3>
        {cell ? (
          <div className="card" data-testid="cell-panel">
            <div>
              Cell <strong data-testid="cell-seq">{cell.seq}</strong>: <span data-testid="cell-rate">{formatRate(cell.rate)}</span>
              {cell.flags ? <span className={cell.clamped ? 'warn' : 'muted'}> ({cell.flags.replace(/,/g, ', ')})</span> : null}
            </div>
            {cell.flags?.includes('no_data') && (
              <p className="warn small" data-testid="cell-no-data">
                No soil sample near this cell: it has the fallback rate
                {attention.fallbackRate != null ? ` ${formatRate(attention.fallbackRate)}` : ''}.
              </p>
            )}
            {cell.clamped && attention.meter && (
              <p className="warn small" data-testid="cell-out-of-range">
                Outside what the machine meters ({formatRate(attention.meter.rate_min_kg_ha)} at{' '}
                {attention.meter.speed_min_kmh} km/h – {formatRate(attention.meter.rate_max_kg_ha)} at{' '}
                {attention.meter.speed_max_kmh} km/h): stored as asked.
              </p>
            )}
            {cell.nCells > 1 ? (
              <p className="muted">
                {cell.nCells} cells are drawn together at this zoom (mean rate shown); zoom in to edit one cell, or paint a
                zone.
              </p>
            ) : (
            <form
              className="row"
              onSubmit={(e) => {
                e.preventDefault();
                void applyEdit({ cells: [{ seq: cell.seq, rate_kg_ha: Number(newRate) }] });
              }}
            >
              <input data-testid="cell-new-rate" type="number" step="any" value={newRate} onChange={(e) => setNewRate(e.target.value)} />
              <button data-testid="cell-save" data-write="">Set rate</button>
            </form>
            )}
          </div>
        ) : (
          <p className="muted">Click a cell to see and edit its rate.</p>
        )}
        <div className="row">
          <button
            data-testid="paint-zone" data-write=""
            className={painting ? 'on' : ''}
            onClick={() => {
              setPainting(true);
              setZone(null);
              drawRef.current?.clear();
              drawRef.current?.setMode('polygon');
            }}
          >
            Paint a zone
          </button>
        </div>
        {zone && (
          <form
            className="row"
            data-testid="zone-panel"
            onSubmit={(e) => {
              e.preventDefault();
              void applyEdit({ zone: { ...zone }, rate_kg_ha: Number(zoneRate) });
            }}
          >
            <input
              data-testid="zone-rate"
              type="number"
              step="any"
              placeholder="kg/ha"
              value={zoneRate}
              onChange={(e) => setZoneRate(e.target.value)}
              required
            />
            <button data-testid="zone-save" data-write="">Apply to zone</button>
          </form>
        )}

        <h3>Export</h3>
        <div className="row wrap">
          {EXPORTS.map(([fmt, label, ext]) => (
            <button
              key={fmt}
              data-testid={`export-${fmt.replace('&profile=', '-')}`}
              onClick={async () => {
                try {
                  const name = await download(
                    `/prescriptions/${rxId}/export?format=${fmt}${version ? `&version=${version}` : ''}`,
                    `prescription-${rxId}-v${version ?? 1}.${ext}`,
                  );
                  setMsg(`Downloaded ${name}`);
                } catch (e) {
                  setError(e);
                }
              }}
            >
              {label}
            </button>
          ))}
        </div>

        <h3>Send to machine</h3>
        <div className="row">
          <select data-testid="job-machine" value={machineId} onChange={(e) => setMachineId(e.target.value)}>
            {machines.map((m) => (
              <option key={m.id} value={m.id}>
                {m.name}
              </option>
            ))}
          </select>
          <button
            data-testid="send-job" data-write=""
            disabled={!machineId}
            onClick={() => void sendJob(false)}
          >
            Send job
          </button>
        </div>
        {confirmJob && (
          <div className="card warn" data-testid="job-confirm-panel" role="alertdialog">
            <p data-testid="job-confirm-text">{confirmJob.message}</p>
            <p className="small">
              Cells: {confirmJob.seq.slice(0, 30).join(', ')}
              {confirmJob.count > 30 ? ' …' : ''}
            </p>
            <div className="row">
              <button data-testid="job-confirm" data-write="" className="danger" onClick={() => void sendJob(true)}>
                Send anyway ({confirmJob.count} flagged)
              </button>
              <button data-testid="job-confirm-cancel" onClick={() => setConfirmJob(null)}>
                Cancel
              </button>
            </div>
          </div>
        )}
      </aside>
      <MapView name="rx" onReady={onReady} fieldId={field?.id} />
    </div>
  );
}

function minOf(xs: number[]): number {
  let m = Infinity;
  for (const x of xs) if (x < m) m = x;
  return m;
}

function maxOf(xs: number[]): number {
  let m = -Infinity;
  for (const x of xs) if (x > m) m = x;
  return m;
}
