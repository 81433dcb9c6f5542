import type { ReactNode } from 'react';
import { NDVI_SOURCE, cropValue, withCrop, withProduct, type Crop, type FieldErrors, type Product, type RxFields, type RxModel } from '../lib/rxform';
import { ProductPicker } from './ProductPicker';

/** A number input with its unit and, under it, where its default comes from or what is wrong. */
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
  const { label, unit, k, f, set, errors, source, tid, step = 'any' } = props;
  return (
    <label className="num-field">
      {label}
      <span className="with-unit">
        <input
          data-testid={`${tid}-${k}`}
          type="number"
          step={step}
          value={f[k]}
          aria-invalid={!!errors[k]}
          onChange={(e) => set({ ...f, [k]: e.target.value })}
        />
        <span className="unit">{unit}</span>
      </span>
      {errors[k] ? (
        <span className="field-error" data-testid={`${tid}-${k}-error`}>
          {errors[k]}
        </span>
      ) : source ? (
        <span className="small muted source">{source}</span>
      ) : null}
    </label>
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
 * N uptake, utilisation; or a uniform rate; or the NDVI curve) and the agronomist's
 * min / max clamp. Each default says where it comes from.
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
      {model !== 'nutrient_balance' && (
        <ProductPicker
          products={products}
          value={f.productKey}
          onChange={(k) => set(withProduct(f, products, k))}
          onAdded={onProductAdded}
          testid={`${tid}-product`}
        />
      )}
      {products.find((p) => p.key === f.productKey)?.density_kg_l ? (
        <label>
          Send to machines in
          <select data-testid={`${tid}-rate-unit`} value={f.rateUnit} onChange={(e) => set({ ...f, rateUnit: e.target.value })}>
            <option value="kg/ha">kg/ha (mass-rate implements)</option>
            <option value="l/ha">l/ha (volume-rate sprayers, through the product's density)</option>
          </select>
          <span className="small muted source">rates are worked out in kg/ha either way</span>
        </label>
      ) : null}
      <div className="row wrap">
        <Num label="Min rate (clamp)" unit="kg/ha" k="clampMin" source="empty: no minimum" {...common} />
        <Num label="Max rate (clamp)" unit="kg/ha" k="clampMax" source="empty: no maximum" {...common} />
      </div>
    </fieldset>
  );
}
