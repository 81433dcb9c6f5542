import { useCallback, useMemo, useRef, useState } from 'react';
import type { TerraDraw } from 'terra-draw';
import { call, client, download, type Schemas } from '../api/client';
import { qk, useExportFormats, useField, useInvalidate, usePlan, usePrescription, usePrescriptionVersion } from '../api/hooks';
import { CellEditPanel, type CellInfo } from '../components/CellEditPanel';
import { Histogram, Legend } from '../components/Legend';
import { RxSummaryPanel } from '../components/RxSummaryPanel';
import { SendJobPanel } from '../components/SendJobPanel';
import { ErrorBox, Kv } from '../components/Status';
import { UndoRedoButtons, useRxHistory } from '../components/UndoRedo';
import { VersionDiff } from '../components/VersionDiff';
import { VersionNote } from '../components/VersionNote';
import { ZonePaintPanel } from '../components/ZonePaintPanel';
import { ZonesTable } from '../components/ZonesTable';
import { classColors, classify, legendEntries, niceBreaks, stepExpression, type LegendEntry } from '../lib/colors';
import { exportMenu, fileType } from '../lib/exportMenu';
import { attentionLines, attentionOf, attentionSummary } from '../lib/flags';
import { bboxOf, type PolygonGeom } from '../lib/geo';
import { rateUnitText, shownUnit } from '../lib/rxform';
import { formatRate, formatUnitRate } from '../lib/units';
import { modelName } from '../lib/words';
import { MapView } from '../map/MapView';
import { rxTilesUrl } from '../map/grid';
import { EDITED_COLOR } from '../map/layers';
import { CellGrid, FieldBoundary, FitBounds, ZoneDraw } from '../map/overlays';

/**
 * Versioned rate map: whole-field figures, legend classes and zones table of the version on
 * screen (all from the server), cell and zone edits with undo / redo, version notes and
 * diff, exports, send to a machine. The map is composed of overlays (no layers added here).
 */
export function PrescriptionScreen({ rxId }: { rxId: number }) {
  const rxQ = usePrescription(rxId);
  const rx = rxQ.data;
  const [picked, setPicked] = useState<number | null>(null);
  const version = picked ?? rx?.current_version ?? null;
  const verQ = usePrescriptionVersion(rxId, version);
  const planQ = usePlan(rx?.plan_id);
  const fieldQ = useField(planQ.data?.field_id);
  const field = fieldQ.data ?? null;
  const [cell, setCell] = useState<CellInfo | null>(null);
  const [zone, setZone] = useState<PolygonGeom | null>(null);
  const [painting, setPainting] = useState(false);
  const [msg, setMsg] = useState('');
  const [error, setError] = useState<unknown>(null);
  const drawRef = useRef<TerraDraw | null>(null);
  const refresh = useInvalidate();
  const formatsQ = useExportFormats();
  const exports = useMemo(() => exportMenu(formatsQ.data?.items ?? [], 'prescription'), [formatsQ.data]);

  /** Make `v` current (undo / redo) and show it. */
  const goTo = useCallback(
    async (v: number) => {
      setError(null);
      try {
        await call(client.PUT('/api/v1/prescriptions/{rx_id}/current', { params: { path: { rx_id: rxId } }, body: { version: v } }));
        await refresh(qk.prescription(rxId));
        setPicked(v);
        setCell(null);
        setMsg(`Version ${v} is current`);
      } catch (e) {
        setError(e);
      }
    },
    [rxId, refresh],
  );
  const history = useRxHistory(goTo);

  // The summary of the version on screen: figures, flags, classes and histogram all follow it.
  const shown = verQ.data?.summary ?? (version === rx?.current_version ? rx?.summary : undefined);
  const attention = attentionOf(shown ? { ...rx, summary: shown } : rx);
  // a prescription in another unit (seeds/ha, ...): its classes and figures in that unit too
  const unit = shownUnit(rx);
  const lo = shown?.rate_min_kg_ha;
  const hi = shown?.rate_max_kg_ha;
  // Legend classes are stored with the version (fixed per version, editable below).
  const stored = shown?.classes?.breaks_kg_ha;
  const breaks = useMemo(() => (stored?.length ? stored : niceBreaks(lo ?? 0, hi ?? 1000, 6)), [stored, lo, hi]);
  const colors = useMemo(() => classColors(breaks.length - 1), [breaks]);
  // cells edited by hand are outlined apart from the rate classes: an edit that lands in an
  // unedited cells' class must still read as an edit on the map and in the legend
  const editedCells = (shown?.flagged?.manual ?? 0) + (shown?.flagged?.zone ?? 0);
  const classRows =
    lo != null && lo === hi
      ? [{ color: colors[0], from: lo, to: lo, label: `${lo.toFixed(1)} (uniform)` }]
      : legendEntries(breaks, colors, (v) => (unit ? formatUnitRate(v, unit.kgPerUnit, '').trim() : v.toFixed(0)));
  const legend: LegendEntry[] = editedCells
    ? [...classRows, { color: EDITED_COLOR, from: 0, to: 0, label: `Edited by hand: ${editedCells} cell${editedCells === 1 ? "" : "s"} (dashed outline)`, outline: true }]
    : classRows;
  const colorExpr = useMemo(() => stepExpression('rate_kg_ha', breaks, colors), [breaks, colors]);
  // Whole-field, area-weighted histogram from the server (never from the tiles on screen).
  const hist = useMemo(() => {
    const h = shown?.histogram;
    if (!h || !h.area_m2.length) return null;
    const mids = h.edges_kg_ha.slice(0, -1).map((e, i) => (e + h.edges_kg_ha[i + 1]) / 2);
    return {
      counts: h.area_m2.map((a) => Math.round(a / 100) / 100),
      colors: mids.map((m) => colors[classify(m, breaks)]),
      labels: h.edges_kg_ha.slice(0, -1).map((e, i) => `${e.toFixed(0)}–${h.edges_kg_ha[i + 1].toFixed(0)} kg/ha`),
    };
  }, [shown, breaks, colors]);

  const applyEdit = async (body: Schemas['EditIn'], what: string) => {
    setError(null);
    try {
      const base = version ?? undefined;
      const r = await call(
        client.POST('/api/v1/prescriptions/{rx_id}/edits', {
          params: { path: { rx_id: rxId } },
          body: { ...body, note: what, based_on_version: base },
        }),
      );
      const v = r.new_version;
      setCell(null);
      setZone(null);
      drawRef.current?.clear();
      await refresh(qk.prescription(rxId));
      setPicked(v);
      if (base != null) history.push({ from: base, to: v, what });
      setMsg(`Saved as version ${v}`);
    } catch (e) {
      setError(e);
    }
  };

  const versions = rx?.versions ?? [];
  const versionNums = versions.map((v) => v.version);
  const note = versions.find((v) => v.version === version)?.note;
  // Tiles are requested once the map can be fitted to the field (or there is none to fit to).
  const canDraw = !!field || fieldQ.isError || planQ.isError;

  return (
    <div className="split">
      <aside className="panel">
        <p>{rx && <a href={`#/plans/${rx.plan_id}`}>← Plan #{rx.plan_id}</a>}</p>
        <h2>
          Prescription #{rxId}
          {rx?.name ? <span className="muted small"> {rx.name}</span> : null}
        </h2>
        <ErrorBox error={error ?? rxQ.error} testid="rx-screen-error" />
        {msg && (
          <p className="ok" data-testid="rx-msg">
            {msg}
          </p>
        )}
        <div className="row">
          <label>
            Version
            <select data-testid="rx-version" value={version ?? ''} onChange={(e) => setPicked(Number(e.target.value))}>
              {versions.map((v) => (
                <option key={v.version} value={v.version}>
                  v{v.version}
                  {v.version === rx?.current_version ? ' (current)' : ''}
                  {v.note ? ` — ${v.note.slice(0, 40)}` : ''}
                </option>
              ))}
            </select>
          </label>
          <UndoRedoButtons h={history} />
        </div>
        <VersionNote rxId={rxId} version={version} note={note} onSaved={() => refresh(qk.prescription(rxId))} />
        <Kv
          items={[
            ['Model', modelName(rx?.model), 'rx-model-name'],
            ['Cells', String(shown?.n_cells ?? '–'), 'rx-cell-count'],
            ['Flagged cells', rx ? attentionSummary(attention) : '–', 'rx-flagged'],
            ['Sent to machines in', rateUnitText(rx, shown?.rate_mean_kg_ha), 'rx-rate-unit'],
          ]}
        />
        <RxSummaryPanel summary={shown} version={version} unit={unit} />
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
        <Legend entries={legend} title={unit ? `Rate (${unit.name})` : 'Rate (kg/ha)'} testid="rx-legend" />
        {hist && <Histogram counts={hist.counts} colors={hist.colors} unit="ha" labels={hist.labels} testid="rx-histogram" />}
        <h3>Zones</h3>
        {version != null && (
          <ZonesTable rxId={rxId} version={version} classes={shown?.classes} colors={colors} onSaved={() => refresh(qk.prescription(rxId))} />
        )}

        <h3>Edit</h3>
        <CellEditPanel
          cell={cell}
          attention={attention}
          onSave={(seq, rate) => void applyEdit({ cells: [{ seq, rate_kg_ha: rate }] }, `cell ${seq} → ${formatRate(rate)}`)}
        />
        <ZonePaintPanel
          zone={zone}
          painting={painting}
          onPaint={() => {
            setZone(null);
            drawRef.current?.clear();
            setPainting(true);
          }}
          onSave={(z, rate) => void applyEdit({ zone: { ...z }, rate_kg_ha: rate }, `zone → ${formatRate(rate)}`)}
        />

        <h3>Compare versions</h3>
        <VersionDiff rxId={rxId} versions={versionNums} shown={version} />

        <h3>Export</h3>
        <div className="row wrap">
          {exports.map(({ query: fmt, label, extension }) => (
            <button
              key={fmt}
              data-testid={`export-${fmt.replace('&profile=', '-')}`}
              onClick={async () => {
                try {
                  const name = await download(
                    `/prescriptions/${rxId}/export?format=${fmt}${version ? `&version=${version}` : ''}`,
                    `prescription-${rxId}-v${version ?? 1}.${fileType(extension)}`,
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
        <SendJobPanel rxId={rxId} version={version} summary={shown} rateUnit={rx?.rate_unit} />
      </aside>
      <MapView name="rx" fieldId={field?.id}>
        <FitBounds bbox={field ? bboxOf(field) : null} />
        {canDraw && version != null && (
          <CellGrid
            id="rx"
            tiles={rxTilesUrl(rxId, version)}
            color={colorExpr}
            clamped
            edited
            selectedSeq={cell?.seq ?? null}
            onClick={(p) => {
              if (painting) return;
              setCell({
                seq: Number(p.seq),
                rate: Number(p.rate_kg_ha),
                flags: (p.flags as string) || '',
                clamped: p.clamped === true,
                nCells: Number(p.n_cells ?? 1) || 1,
              });
            }}
          />
        )}
        <FieldBoundary data={field} fill={false} />
        <ZoneDraw
          mode={painting ? 'polygon' : 'static'}
          onReady={(d) => {
            drawRef.current = d;
          }}
          onFinish={(id, d) => {
            const f = d.getSnapshotFeature(id);
            if (f?.geometry.type === 'Polygon') setZone(f.geometry as PolygonGeom);
            setPainting(false);
          }}
        />
      </MapView>
    </div>
  );
}
