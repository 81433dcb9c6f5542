import { useState } from 'react';
import { call, client } from '../api/client';
import { productText, type Product } from '../lib/rxform';
import { ErrorBox } from './Status';

/**
 * Product from the catalogue (defaults named by their source, the organisation's own
 * products) with its nutrient % and price, and an inline form to add one.
 */
export function ProductPicker(props: {
  products: Product[];
  value: string;
  onChange: (key: string) => void;
  onAdded: (p: Product) => Promise<void> | void;
  error?: string;
  testid?: string;
}) {
  const { products, value, onChange, onAdded, error, testid = 'rx-product' } = props;
  const [adding, setAdding] = useState(false);
  const [name, setName] = useState('');
  const [npk, setNpk] = useState({ n: '', p: '0', k: '0' });
  const [price, setPrice] = useState('');
  const [density, setDensity] = useState('');
  const [addError, setAddError] = useState<unknown>(null);
  const chosen = products.find((p) => p.key === value);
  const save = async () => {
    setAddError(null);
    try {
      const p = await call(
        client.POST('/api/v1/products', {
          body: {
            name,
            n_pct: Number(npk.n),
            p2o5_pct: Number(npk.p || 0),
            k2o_pct: Number(npk.k || 0),
            price_per_t: price.trim() === '' ? null : Number(price),
            density_kg_l: density.trim() === '' ? null : Number(density),
          },
        }),
      );
      await onAdded(p);
      onChange(p.key);
      setAdding(false);
      setName('');
      setDensity('');
    } catch (e) {
      setAddError(e);
    }
  };
  return (
    <div className="product-picker">
      <label>
        Product
        <select data-testid={testid} value={value} onChange={(e) => onChange(e.target.value)} aria-invalid={!!error}>
          <option value="">— choose —</option>
          {products.map((p) => (
            <option key={p.key} value={p.key}>
              {p.name}
              {p.id != null ? ' (organisation)' : ''}
            </option>
          ))}
        </select>
      </label>
      {error && (
        <div className="field-error" data-testid={`${testid}-error`}>
          {error}
        </div>
      )}
      {chosen && (
        <div className="small muted" data-testid={`${testid}-info`}>
          {productText(chosen)} — {chosen.source}
        </div>
      )}
      {!adding ? (
        <button type="button" className="link" data-testid={`${testid}-add`} onClick={() => setAdding(true)}>
          + Add a product
        </button>
      ) : (
        <div className="card" data-testid={`${testid}-new`}>
          <label>
            Name
            <input data-testid="product-name" value={name} onChange={(e) => setName(e.target.value)} />
          </label>
          <div className="row wrap">
            {(
              [
                ['n', 'N %'],
                ['p', 'P₂O₅ %'],
                ['k', 'K₂O %'],
              ] as const
            ).map(([k, label]) => (
              <label key={k}>
                {label}
                <input
                  data-testid={`product-${k}`}
                  type="number"
                  min={0}
                  max={100}
                  step="any"
                  value={npk[k]}
                  onChange={(e) => setNpk({ ...npk, [k]: e.target.value })}
                />
              </label>
            ))}
            <label>
              Price per t
              <input data-testid="product-price" type="number" min={0} step="any" value={price} onChange={(e) => setPrice(e.target.value)} />
            </label>
            <label>
              Density kg/l (liquids)
              <input
                data-testid="product-density"
                type="number"
                min={0.05}
                max={5}
                step="any"
                placeholder="solid: empty"
                value={density}
                onChange={(e) => setDensity(e.target.value)}
              />
            </label>
          </div>
          <div className="row">
            <button type="button" data-testid="product-save" data-write="" onClick={() => void save()}>
              Add product
            </button>
            <button type="button" onClick={() => setAdding(false)}>
              Cancel
            </button>
          </div>
          <ErrorBox error={addError} testid="product-error" />
        </div>
      )}
    </div>
  );
}
