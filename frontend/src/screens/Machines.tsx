import { useCallback, useEffect, useState } from 'react';
import { api } from '../api';
import { ErrorBox } from '../components/Status';
import type { Machine } from '../types';
import { listOf } from '../types';

/** Machine register: create implements with width, lag and metering calibration. */
export function MachinesScreen() {
  const [machines, setMachines] = useState<Machine[]>([]);
  const [error, setError] = useState<unknown>(null);
  const [name, setName] = useState('');
  const [width, setWidth] = useState('12');
  const [lag, setLag] = useState('1.52');
  const load = useCallback(async () => {
    try {
      setMachines(listOf<Machine>(await api.get('/machines')));
    } catch (e) {
      setError(e);
    }
  }, []);
  useEffect(() => void load(), [load]);
  return (
    <div className="page">
      <h2>Machines</h2>
      <ErrorBox error={error} />
      <form
        className="row"
        onSubmit={async (e) => {
          e.preventDefault();
          try {
            await api.post('/machines', {
              name,
              implement_type: 'spreader',
              width_m: Number(width),
              lag_s: Number(lag),
              // seed 001 eq. 1 calibration (SCIENCE.md)
              calibration: { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 },
            });
            setName('');
            await load();
          } catch (err) {
            setError(err);
          }
        }}
      >
        <input data-testid="machine-name" placeholder="Name" value={name} onChange={(e) => setName(e.target.value)} required />
        <label className="inline">
          width m <input type="number" step="0.1" value={width} onChange={(e) => setWidth(e.target.value)} />
        </label>
        <label className="inline">
          lag s <input type="number" step="0.01" value={lag} onChange={(e) => setLag(e.target.value)} />
        </label>
        <button data-testid="machine-submit" data-write="">Add machine</button>
      </form>
      <table className="table" data-testid="machine-table">
        <thead>
          <tr>
            <th>Name</th>
            <th>Implement</th>
            <th>Width</th>
            <th>Lag</th>
          </tr>
        </thead>
        <tbody>
          {machines.map((m) => (
            <tr key={m.id}>
              <td>
                <a href={`#/machines/${m.id}`} data-testid={`machine-link-${m.id}`}>
                  {m.name}
                </a>
              </td>
              <td>{m.implement_type ?? '–'}</td>
              <td>{m.width_m != null ? `${m.width_m} m` : '–'}</td>
              <td>{m.lag_s != null ? `${m.lag_s} s` : '–'}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}
