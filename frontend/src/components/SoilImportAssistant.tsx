import { useRef, useState } from 'react';
import { ApiError, call, client, download, formBody, type Schemas } from '../api/client';
import { NO_TARGET, remap, type MappingIn } from '../lib/soilMapping';
import { ErrorBox } from './Status';

type Preview = Schemas['SoilLabPreview'];
type OutsideRow = Schemas['OutsideRow'];
type Options = { mode: 'append' | 'replace'; includeOutside: boolean; skipRejected: boolean };

/**
 * Soil-lab import assistant: choose a file, check the column mapping the server proposes
 * (quantity and unit per column, coordinate system), see the converted rows, the rejected
 * rows with their reason and the rows outside the field, then confirm. Nothing is stored
 * before "Import"; the server stores all of it or nothing.
 */
export function SoilImportAssistant({ fieldId, onImported }: { fieldId: number; onImported: (msg: string) => void }) {
  const [file, setFile] = useState<File | null>(null);
  const [preview, setPreview] = useState<Preview | null>(null);
  const [mapping, setMapping] = useState<MappingIn | null>(null);
  const [opts, setOpts] = useState<Options>({ mode: 'append', includeOutside: false, skipRejected: false });
  const [error, setError] = useState<unknown>(null);
  const [busy, setBusy] = useState(false);
  const [outside, setOutside] = useState<OutsideRow[]>([]);
  const fileRef = useRef<HTMLInputElement>(null);
  const path = { field_id: fieldId };

  const body = (f: File, m: MappingIn | null) => {
    const fd = new FormData();
    fd.append('file', f);
    if (m) fd.append('mapping', JSON.stringify(m));
    return formBody(fd);
  };

  const runPreview = async (f: File, m: MappingIn | null) => {
    setBusy(true);
    setError(null);
    try {
      const p = await call(client.POST('/api/v1/fields/{field_id}/soil-imports/preview', { params: { path }, ...body(f, m) }));
      setPreview(p);
      setMapping(p.mapping);
      setOutside(p.outside);
    } catch (e) {
      setPreview(null);
      setError(e);
    } finally {
      setBusy(false);
    }
  };

  const change = (m: MappingIn) => {
    setMapping(m);
    if (file) void runPreview(file, m);
  };

  const confirm = async () => {
    if (!file || !mapping) return;
    setBusy(true);
    setError(null);
    try {
      const query = {
        mode: opts.mode,
        include_outside: opts.includeOutside || undefined,
        skip_rejected: opts.skipRejected || undefined,
      };
      const r = await call(
        client.POST('/api/v1/fields/{field_id}/soil-imports', { params: { path, query }, ...body(file, mapping) }),
      );
      setPreview(null);
      setFile(null);
      setOutside(r.outside);
      onImported(`Imported ${file.name}: ${r.message}`);
    } catch (e) {
      const b = e instanceof ApiError ? (e.body as Schemas['ErrorOut'] | null) : null;
      if (b && Array.isArray(b.outside)) setOutside(b.outside as OutsideRow[]);
      setError(e);
    } finally {
      setBusy(false);
    }
  };

  const targetOf = (t: string) => preview?.targets.find((x) => x.target === t);
  const nStore = preview ? (opts.includeOutside ? preview.n_accepted : preview.n_inside) : 0;
  const blocked = !preview || !preview.mapping_ok || nStore === 0 || (preview.n_rejected > 0 && !opts.skipRejected);
  const epsgKnown = preview?.crs_options.some((o) => o.epsg === mapping?.epsg);

  return (
    <div className="card" data-testid="soil-assistant">
      <div className="row">
        {/* a real button (keyboard reachable, unlike a label around a hidden input) */}
        <button type="button" data-testid="soil-file-button" data-write="" onClick={() => fileRef.current?.click()}>
          Import lab file…
        </button>
        <input
          ref={fileRef}
          data-testid="soil-file"
          data-write=""
          type="file"
          accept=".csv,.txt,.tsv,.geojson,.json"
          hidden
          onChange={(e) => {
            const f = e.target.files?.[0];
            e.target.value = '';
            if (!f) return;
            setFile(f);
            setOutside([]);
            void runPreview(f, null);
          }}
        />
        <button
          type="button"
          className="link"
          data-testid="soil-example"
          onClick={() => download(`/fields/${fieldId}/soil-imports/example.csv`, 'soil_lab_example.csv').catch(setError)}
        >
          Example file
        </button>
        {busy && <span className="muted" data-testid="soil-busy">Reading…</span>}
      </div>
      <ErrorBox error={error} testid="soil-error" />
      {preview && mapping && (
        <div data-testid="soil-mapping">
          <p className="muted small">
            {preview.filename}: {preview.n_rows} rows, separator “{preview.delimiter === '\t' ? 'tab' : preview.delimiter}”
            {preview.decimal_comma ? ', decimal comma' : ''}, {preview.encoding}
          </p>
          <table className="table" data-testid="soil-columns">
            <thead>
              <tr>
                <th>Column in the file</th>
                <th>Is / unit</th>
              </tr>
            </thead>
            <tbody>
              {preview.columns.map((c) => {
                const t = c.target ?? NO_TARGET;
                const spec = t ? targetOf(t) : undefined;
                const units = spec?.units ?? [];
                const unit = mapping.units[t] ?? spec?.default_unit ?? '';
                return (
                  <tr key={c.name} data-testid={`soil-col-${c.name}`}>
                    <td>
                      <strong>{c.name}</strong>
                      <div className="muted small" title={c.examples.join(' · ')}>
                        {c.examples.slice(0, 2).join(' · ')}
                      </div>
                    </td>
                    <td>
                      <select
                        aria-label={`${c.name} is`}
                        data-testid="soil-col-target"
                        value={t}
                        onChange={(e) => change(remap(mapping, c.name, e.target.value))}
                      >
                        <option value={NO_TARGET}>— not read —</option>
                        {preview.targets.map((x) => (
                          <option key={x.target} value={x.target}>
                            {x.label}
                          </option>
                        ))}
                      </select>
                      {units.length > 0 && (
                        <div>
                          <select
                            aria-label={`${c.name} unit`}
                            data-testid="soil-col-unit"
                            value={unit}
                            onChange={(e) => change({ ...mapping, units: { ...mapping.units, [t]: e.target.value } })}
                          >
                            {units.map((u) => (
                              <option key={u} value={u}>
                                {u}
                              </option>
                            ))}
                          </select>
                          {spec?.stored_unit && unit !== spec.stored_unit && (
                            <span className="muted small"> → {spec.stored_unit}</span>
                          )}
                        </div>
                      )}
                    </td>
                  </tr>
                );
              })}
            </tbody>
          </table>
          <label>
            Coordinates (x/y) are in{' '}
            <select
              data-testid="soil-crs"
              value={epsgKnown ? String(mapping.epsg) : mapping.epsg == null ? '' : 'other'}
              onChange={(e) =>
                e.target.value !== 'other' && change({ ...mapping, epsg: e.target.value ? Number(e.target.value) : null })
              }
            >
              <option value="">— choose —</option>
              {preview.crs_options.map((o) => (
                <option key={o.epsg} value={o.epsg}>
                  {o.name} (EPSG:{o.epsg})
                </option>
              ))}
              <option value="other">other EPSG code…</option>
            </select>
          </label>
          {!epsgKnown && mapping.epsg != null && <span className="muted"> EPSG:{mapping.epsg}</span>}
          <label className="inline">
            EPSG{' '}
            <input
              data-testid="soil-epsg"
              type="number"
              style={{ width: '7em' }}
              defaultValue={mapping.epsg ?? ''}
              key={mapping.epsg ?? 'none'}
              onBlur={(e) => {
                const v = Number(e.target.value);
                if (e.target.value && v !== mapping.epsg) change({ ...mapping, epsg: v });
              }}
            />
          </label>
          {mapping.columns.n && (
            <label className="inline">
              N form of column “{mapping.columns.n}”{' '}
              <select
                data-testid="soil-n-form"
                value={mapping.n_form ?? 'alkali_hydrolysable'}
                onChange={(e) => change({ ...mapping, n_form: e.target.value as NonNullable<MappingIn['n_form']> })}
              >
                <option value="alkali_hydrolysable">alkali-hydrolysable N (seed 001, nutrient balance)</option>
                <option value="mineral">mineral N (Nmin)</option>
                <option value="total">total N</option>
              </select>
              {(mapping.n_form ?? 'alkali_hydrolysable') !== 'alkali_hydrolysable' && (
                <span className="warn small"> the nutrient-balance model reads only alkali-hydrolysable N</span>
              )}
            </label>
          )}
          {mapping.units.n === 'kg/ha' && (
            <label className="inline">
              Bulk density for Nmin kg/ha → mg/kg (g/cm³){' '}
              <input
                data-testid="soil-bulk-density"
                type="number"
                step="0.05"
                style={{ width: '5em' }}
                defaultValue={mapping.bulk_density_g_cm3}
                onBlur={(e) => {
                  const v = Number(e.target.value);
                  if (v && v !== mapping.bulk_density_g_cm3) change({ ...mapping, bulk_density_g_cm3: v });
                }}
              />
            </label>
          )}
          <p data-testid="soil-counts">
            <strong>{preview.n_accepted}</strong> of {preview.n_rows} rows read, <strong>{preview.n_inside}</strong> inside
            the field, <strong data-testid="soil-n-outside">{preview.n_outside}</strong> outside (&gt; {preview.outside_tolerance_m} m),{' '}
            <strong data-testid="soil-n-rejected">{preview.n_rejected}</strong> rejected
          </p>
          {preview.rejected.length > 0 && (
            <div className="card warn" data-testid="soil-rejected">
              {preview.mapping_ok ? 'Rejected rows:' : 'The mapping is not complete:'}
              <ul>
                {preview.rejected.slice(0, 50).map((r, i) => (
                  <li key={i}>
                    {r.kind === 'header' ? 'header' : `${r.kind} ${r.row}`}
                    {r.column ? `, ${r.column}` : ''}: {r.message}
                  </li>
                ))}
              </ul>
              {preview.rejected.length > 50 && <p className="muted">and {preview.rejected.length - 50} more</p>}
            </div>
          )}
          {preview.rows.length > 0 && (
            <div className="scroll">
              <table className="table" data-testid="soil-preview-rows">
                <thead>
                  <tr>
                    <th>Row</th>
                    <th>Sample</th>
                    <th>Lon</th>
                    <th>Lat</th>
                    <th>Depth cm</th>
                    <th>N mg/kg</th>
                    <th>P mg/kg</th>
                    <th>K mg/kg</th>
                    <th>OM g/kg</th>
                    <th>pH</th>
                  </tr>
                </thead>
                <tbody>
                  {preview.rows.map((r) => (
                    <tr key={r.row}>
                      <td>{r.row}</td>
                      <td>{r.sample_id}</td>
                      <td>{r.lon.toFixed(6)}</td>
                      <td>{r.lat.toFixed(6)}</td>
                      {[r.depth_cm, r.n_mg_kg, r.p_mg_kg, r.k_mg_kg, r.om_g_kg, r.ph].map((v, i) => (
                        <td key={i}>{v == null ? '' : Math.round(v * 100) / 100}</td>
                      ))}
                    </tr>
                  ))}
                </tbody>
              </table>
            </div>
          )}
          <fieldset className="row">
            <label className="inline">
              <input
                type="radio"
                name="soil-mode"
                data-testid="soil-mode-append"
                checked={opts.mode === 'append'}
                onChange={() => setOpts({ ...opts, mode: 'append' })}
              />{' '}
              add to the {preview.n_existing} samples of the field
            </label>
            <label className="inline">
              <input
                type="radio"
                name="soil-mode"
                data-testid="soil-mode-replace"
                checked={opts.mode === 'replace'}
                onChange={() => setOpts({ ...opts, mode: 'replace' })}
              />{' '}
              replace them
            </label>
            <label className="inline">
              <input
                type="checkbox"
                data-testid="soil-include-outside"
                checked={opts.includeOutside}
                onChange={(e) => setOpts({ ...opts, includeOutside: e.target.checked })}
              />{' '}
              also store rows outside the field
            </label>
            {preview.n_rejected > 0 && (
              <label className="inline">
                <input
                  type="checkbox"
                  data-testid="soil-skip-rejected"
                  checked={opts.skipRejected}
                  onChange={(e) => setOpts({ ...opts, skipRejected: e.target.checked })}
                />{' '}
                leave the {preview.n_rejected} rejected rows out
              </label>
            )}
          </fieldset>
          <div className="row">
            <button data-testid="soil-confirm" data-write="" disabled={busy || blocked} onClick={() => void confirm()}>
              Import {nStore} samples{opts.mode === 'replace' ? ` (replacing ${preview.n_existing})` : ''}
            </button>
            <button
              type="button"
              data-testid="soil-cancel"
              onClick={() => {
                setPreview(null);
                setFile(null);
                setError(null);
              }}
            >
              Cancel
            </button>
          </div>
        </div>
      )}
      {outside.length > 0 && (
        <div className="card warn" data-testid="soil-outside">
          {outside.length} row{outside.length === 1 ? '' : 's'} outside the field:
          <ul>
            {outside.slice(0, 20).map((o) => (
              <li key={o.row}>
                row {o.row} ({o.sample_id})
                {o.distance_m != null ? `: ${Math.round(o.distance_m).toLocaleString('en')} m away` : ''}
              </li>
            ))}
          </ul>
          {outside.length > 20 && <p className="muted">and {outside.length - 20} more</p>}
        </div>
      )}
    </div>
  );
}
