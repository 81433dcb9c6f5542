import { useEffect, useRef, type ReactNode } from 'react';
import { rateModel } from '../lib/rateModels';
import { RATE_UNITS, rateUnit } from '../lib/rateUnits';
import {
  NDVI_SOURCE,
  cropValue,
  genericParams,
  paramLabel,
  paramText,
  paramUnit,
  productLotValue,
  unitLot,
  withCrop,
  withProduct,
  withProductLot,
  type Crop,
  type FieldErrors,
  type Product,
  type RxFields,
  type RxModel,
} from '../lib/rxform';
import { ProductPicker } from './ProductPicker';

/** A number input with its unit and, under it, where its value comes from or what is wrong. */
function NumInput(props: {
  label: string;
  unit: string;
  value: string;
  onChange: (v: string) => void;
  error?: string;
  source?: ReactNode;
  testid: string;
  min?: number;
  max?: number;
  step?: string;
}) {
  const { label, unit, value, onChange, error, source, testid, min, max, step = 'any' } = props;
  return (
    <label className="num-field">
      {label}
      <span className="with-unit">
        <input
          data-testid={testid}
          type="number"
          step={step}
          min={min}
          max={max}
          value={value}
          aria-invalid={!!error}
          onChange={(e) => onChange(e.target.value)}
        />
        <span className="unit">{unit}</span>
      </span>
      {error ? (
        <span className="field-error" data-testid={`${testid}-error`}>
          {error}
        </span>
      ) : source ? (
        <span className="small muted source">{source}</span>
      ) : null}
    </label>
  );
}

/** A number field of RxFields (testid `${tid}-${k}`). */
function Num(props: {
  label: string;
  unit: string;
  k: keyof RxFields;
  f: RxFields;
  set: (f: RxFields) => void;
  errors: FieldErrors;
  source?: ReactNode;
  tid: string;
  step?: string;
}) {
  const { label, unit, k, f, set, errors, source, tid, step } = props;
  return (
    <NumInput
      label={label}
      unit={unit}
      value={f[k] as string}
      onChange={(v) => set({ ...f, [k]: v })}
      error={errors[k]}
      source={source}
      testid={`${tid}-${k}`}
      step={step}
    />
  );
}

/** Every default of the crop with its unit and source (uptake of N, P2O5, K2O, ceilings, ...). */
function CropTable({ crop, tid }: { crop: Crop; tid: string }) {
  return (
    <details className="small" data-testid={`${tid}-crop-values`}>
      <summary>{crop.name}: every default and its source</summary>
      <table>
        <tbody>
          {Object.entries(crop.values).map(([k, v]) => (
            <tr key={k} data-testid={`${tid}-crop-value-${k}`}>
              <th>{k}</th>
              <td>
                {v.value} {v.unit}
              </td>
              <td className="muted source">{v.source}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </details>
  );
}

/**
 * The rate model's inputs as typed fields with units (crop, target yield t/ha, product,
 * N uptake, utilisation; or a uniform rate; or the NDVI curve; for any other model one input
 * per parameter the server's registry declares), the unit the rates go to machines in with
 * the product lot values it converts through, and the agronomist's min / max clamp. Each
 * default says where it comes from.
 */
export function RxModelFields(props: {
  model: RxModel;
  fields: RxFields;
  setFields: (f: RxFields) => void;
  errors: FieldErrors;
  crops: Crop[];
  products: Product[];
  onProductAdded: () => Promise<void>;
  tid?: string;
}) {
  const { model, fields: f, setFields: set, errors, crops, products, onProductAdded, tid = 'rx' } = props;
  const crop = crops.find((c) => c.key === f.crop);
  // the form field each crop default fills; a value that differs from the default is the user's
  const FIELD_OF: Record<string, keyof RxFields> = {
    target_yield_t_ha: 'targetYieldTHa',
    e_kg_per_100kg: 'eKgPer100kg',
    k_utilisation: 'kUtilisation',
    d_intercept_pct: 'dIntercept',
    d_slope_pct_mg_kg: 'dSlope',
  };
  const cropSource = (k: string) => {
    const v = crop?.values?.[k];
    if (!crop || !v) return 'set by you';
    return cropValue(crop, k) === f[FIELD_OF[k]] ? `default: ${crop.name}, ${v.source}` : `set by you (default ${v.value}: ${v.source})`;
  };
  const common = { f, set, errors, tid };
  const product = products.find((p) => p.key === f.productKey);
  // a product just added is in the catalogue only once it is read again: its lot values
  // (density, ...) fill in then
  // (when the catalogue or the product changes only: a value the user clears stays cleared)
  const latest = useRef({ f, set });
  useEffect(() => {
    latest.current = { f, set };
  });
  useEffect(() => {
    const { f: now, set: update } = latest.current;
    const next = withProductLot(now, products);
    if (next !== now) update(next);
  }, [products, f.productKey]);
  const info = rateModel(model);
  // a unit that sows a seed lot: no fertiliser from the catalogue, the seed is named here
  const seedLot = rateUnit(f.rateUnit)?.seed_lot === true;
  const lotSource = (key: string) => {
    const had = productLotValue(product, key);
    if (!had) return 'this lot (the product does not state it)';
    return had === f.lot?.[key] ? `from ${product?.name}` : `the product states ${had}: give one of them`;
  };
  return (
    <fieldset className="rx-fields">
      {model === 'nutrient_balance' && (
        <>
          <label>
            Crop
            <select
              data-testid={`${tid}-crop`}
              value={f.crop}
              onChange={(e) => {
                const c = crops.find((x) => x.key === e.target.value);
                if (c) set(withCrop(f, c));
              }}
            >
              {crops.map((c) => (
                <option key={c.key} value={c.key}>
                  {c.name}
                </option>
              ))}
            </select>
          </label>
          <Num label="Target yield" unit="t/ha" k="targetYieldTHa" source={cropSource('target_yield_t_ha')} {...common} />
          <ProductPicker
            products={products}
            value={f.productKey}
            onChange={(k) => set(withProduct(f, products, k))}
            onAdded={onProductAdded}
            error={errors.productKey}
            testid={`${tid}-product`}
          />
          <details>
            <summary>Crop N uptake, utilisation and soil correction</summary>
            <Num label="N uptake" unit="kg N / 100 kg yield" k="eKgPer100kg" source={cropSource('e_kg_per_100kg')} {...common} />
            <Num label="Fertiliser N utilisation" unit="fraction" k="kUtilisation" source={cropSource('k_utilisation')} {...common} />
            <Num label="Soil correction a (eq. 20)" unit="%" k="dIntercept" source={cropSource('d_intercept_pct')} {...common} />
            <Num label="Soil correction b (eq. 20)" unit="% mg/kg" k="dSlope" source={cropSource('d_slope_pct_mg_kg')} {...common} />
          </details>
          {crop && <CropTable crop={crop} tid={tid} />}
        </>
      )}
      {model === 'uniform' && <Num label="Rate" unit="kg/ha" k="uniformRate" {...common} />}
      {model === 'ndvi' && (
        <div className="row wrap">
          <Num label="NDVI low" unit="" k="ndviLow" source={NDVI_SOURCE} {...common} />
          <Num label="Rate at NDVI low" unit="kg/ha" k="rateAtLow" source={NDVI_SOURCE} {...common} />
          <Num label="NDVI high" unit="" k="ndviHigh" source={NDVI_SOURCE} {...common} />
          <Num label="Rate at NDVI high" unit="kg/ha" k="rateAtHigh" source={NDVI_SOURCE} {...common} />
        </div>
      )}
      {info && genericParams(model).length > 0 && (
        <div className="row wrap">
          {genericParams(model).map((p) => (
            <NumInput
              key={p.name}
              label={paramLabel(p.name)}
              unit={paramUnit(info, p, f.rateUnit)}
              value={paramText(f, model, p)}
              onChange={(v) => set({ ...f, modelParams: { ...f.modelParams, [model]: { ...f.modelParams?.[model], [p.name]: v } } })}
              error={errors[`param.${p.name}`]}
              source={p.default != null ? `default: ${p.source}` : p.source}
              testid={`${tid}-param-${p.name}`}
            />
          ))}
        </div>
      )}
      {model !== 'nutrient_balance' && seedLot && (
        <label>
          Seed (variety, lot)
          <input data-testid={`${tid}-seed-name`} value={f.seedName ?? ''} onChange={(e) => set({ ...f, seedName: e.target.value })} />
          <span className="small muted source">a seed lot, not a catalogue fertiliser: its values are given below</span>
        </label>
      )}
      {model !== 'nutrient_balance' && !seedLot && (
        <ProductPicker
          products={products}
          value={f.productKey}
          onChange={(k) => set(withProduct(f, products, k))}
          onAdded={onProductAdded}
          testid={`${tid}-product`}
        />
      )}
      <label>
        Send to machines in
        <select data-testid={`${tid}-rate-unit`} value={f.rateUnit} onChange={(e) => set(withProductLot({ ...f, rateUnit: e.target.value }, products))}>
          {RATE_UNITS.map((u) => (
            <option key={u.name} value={u.name}>
              {u.label}
              {u.lot.length ? ` (through the lot's ${u.lot.map((v) => v.label).join(', ')})` : ''}
            </option>
          ))}
        </select>
        <span className="small muted source">rates are worked out in {RATE_UNITS[0]?.name} either way</span>
      </label>
      {unitLot(f.rateUnit).length > 0 && (
        <div className="row wrap" data-testid={`${tid}-lot`}>
          {unitLot(f.rateUnit).map((v) => (
            <NumInput
              key={v.key}
              label={`${seedLot ? 'Seed lot' : 'Product'} ${v.label}`}
              unit={v.unit}
              value={f.lot?.[v.key] ?? ''}
              onChange={(x) => set({ ...f, lot: { ...f.lot, [v.key]: x } })}
              error={errors[`lot.${v.key}`]}
              source={`${lotSource(v.key)} · ${v.min}-${v.max} ${v.unit}`}
              testid={`${tid}-lot-${v.key}`}
              min={v.min}
              max={v.max}
            />
          ))}
        </div>
      )}
      <div className="row wrap">
        <Num label="Min rate (clamp)" unit="kg/ha" k="clampMin" source="empty: no minimum" {...common} />
        <Num label="Max rate (clamp)" unit="kg/ha" k="clampMax" source="empty: no maximum" {...common} />
      </div>
    </fieldset>
  );
}
