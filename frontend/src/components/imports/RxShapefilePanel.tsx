import { useEffect, useState } from 'react';
import { call, client } from '../../api/client';
import { ErrorBox } from '../Status';
import { Confirm, filesBody, num, usePreview, type Dict, type Done, type Field, type Row } from './parts';

/** A prescription Shapefile: field, rate column, unit (density for volume rates), default rate. */
export function RxShapefilePanel({ file, fields, onDone }: { file: File; fields: Field[]; onDone: Done }) {
  const [fieldId, setFieldId] = useState(fields[0] ? String(fields[0].id) : '');
  const [col, setCol] = useState('');
  const [unit, setUnit] = useState('kg/ha');
  const [dflt, setDflt] = useState('0');
  const [density, setDensity] = useState('');
  const q = (extra: Dict) => ({
    field_id: Number(fieldId),
    ...(col ? { rate_column: col, unit, default_rate_kg_ha: Number(dflt) || 0 } : {}),
    ...(density ? { density_kg_l: Number(density) } : {}),
    ...extra,
  });
  const pre = usePreview(
    fieldId
      ? () => call(client.POST('/api/v1/imports/prescription-shapefile', { params: { query: q({}) as never }, ...filesBody([file], 'file') }))
      : null,
    [file, fieldId, col, unit, dflt, density],
  );
  const d = pre.data as Row | null;
  useEffect(() => {
    if (d && !col && d.suggested_rate_column) setCol(d.suggested_rate_column);
  }, [d, col]);
  return (
    <div data-testid="import-rx-shapefile">
      <label>
        For field{' '}
        <select data-testid="import-target-field" value={fieldId} onChange={(e) => setFieldId(e.target.value)}>
          {fields.map((f) => (
            <option key={f.id} value={f.id}>
              {f.properties.name}
            </option>
          ))}
        </select>
      </label>
      <ErrorBox error={pre.error} testid="import-preview-error" />
      {d && (
        <>
          <p className="muted">{d.features} polygons</p>
          <div className="row">
            <label>
              Rate column{' '}
              <select data-testid="import-rate-column" value={col} onChange={(e) => setCol(e.target.value)}>
                <option value="">–</option>
                {Object.entries(d.numeric_columns as Record<string, Row>).map(([c, s]) => (
                  <option key={c} value={c}>
                    {c} ({num(s.min)}–{num(s.max)})
                  </option>
                ))}
              </select>
            </label>
            <label>
              Unit{' '}
              <select data-testid="import-unit" value={unit} onChange={(e) => setUnit(e.target.value)}>
                {(d.units as string[]).map((u) => (
                  <option key={u}>{u}</option>
                ))}
              </select>
            </label>
            {/l/.test(unit) && (
              <label>
                Density kg/l <input data-testid="import-density" type="number" step="0.01" value={density} onChange={(e) => setDensity(e.target.value)} />
              </label>
            )}
            <label>
              Rate outside the zones (kg/ha){' '}
              <input data-testid="import-default-rate" type="number" min="0" value={dflt} onChange={(e) => setDflt(e.target.value)} />
            </label>
          </div>
          {d.mapping && (
            <p data-testid="import-mapping">
              {d.mapping.rate_column} in {d.mapping.unit}: {num(d.mapping.min_rate_kg_ha)}–{num(d.mapping.max_rate_kg_ha)} kg/ha, {num(d.mapping.default_rate_kg_ha)} kg/ha
              outside the zones
            </p>
          )}
          <Confirm
            label="Import prescription"
            disabled={!d.mapping}
            onConfirm={async () => {
              const r = await call(
                client.POST('/api/v1/imports/prescription-shapefile', {
                  params: { query: q({ confirm: d.sha256 }) as never },
                  ...filesBody([file], 'file'),
                }),
              );
              onDone(`Imported prescription ${r.created?.prescription_id}`, `#/prescriptions/${r.created?.prescription_id}`);
            }}
          />
        </>
      )}
    </div>
  );
}

