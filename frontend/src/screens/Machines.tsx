import { useState } from 'react';
import { call, client, type Schemas } from '../api/client';
import { qk, useApiMutation, useMachines } from '../api/hooks';
import { ErrorBox } from '../components/Status';
import {
  calibrationText,
  EMPTY_CALIBRATION,
  meterableRange,
  validateCalibration,
  type CalibrationErrors,
  type CalibrationForm,
} from '../lib/calibration';

const FIELDS: [keyof CalibrationForm, string, string][] = [
  ['slope', 'a (g/min per r/min)', 'cal-slope'],
  ['intercept', 'b (g/min)', 'cal-intercept'],
  ['minRpm', 'min r/min', 'cal-min-rpm'],
  ['maxRpm', 'max r/min', 'cal-max-rpm'],
  ['lag', 'lag s', 'cal-lag'],
];

/** Machine register: create implements with width, lag time and their measured metering calibration. */
export function MachinesScreen() {
  const machinesQ = useMachines();
  const machines = machinesQ.data?.items ?? [];
  const [name, setName] = useState('');
  const [width, setWidth] = useState('12');
  const [speedMin, setSpeedMin] = useState('3');
  const [speedMax, setSpeedMax] = useState('9');
  const [cal, setCal] = useState<CalibrationForm>(EMPTY_CALIBRATION);
  // the implement and what it can do beyond metering (checked when a job is made and sent)
  const [impl, setImpl] = useState<{ type: Schemas['MachineIn']['implement_type']; caps: Schemas['CapabilitiesIn'] }>({
    type: 'spreader',
    caps: { depth_actuator: false, sensors: [] },
  });
  const sensors = impl.caps.sensors ?? [];
  const toggleSensor = (x: 'canopy_ndvi' | 'depth') =>
    setImpl({ ...impl, caps: { ...impl.caps, sensors: sensors.includes(x) ? sensors.filter((y) => y !== x) : [...sensors, x] } });
  const [calErrors, setCalErrors] = useState<CalibrationErrors>({});
  const create = useApiMutation((body: Schemas['MachineIn']) => call(client.POST('/api/v1/machines', { body })), {
    invalidate: () => [qk.machines(), qk.machineStatus()],
  });
  const error = create.error ?? machinesQ.error;
  const checked = validateCalibration(cal);
  const w = Number(width);
  const range =
    checked.value && w > 0 && Number(speedMin) > 0 && Number(speedMax) >= Number(speedMin)
      ? meterableRange(checked.value.calibration, w, Number(speedMin) / 3.6, Number(speedMax) / 3.6)
      : null;
  return (
    <div className="page">
      <h2>Machines</h2>
      <ErrorBox error={error} />
      <form
        className="card"
        data-testid="machine-form"
        noValidate
        onSubmit={(e) => {
          e.preventDefault();
          const r = validateCalibration(cal);
          setCalErrors(r.errors);
          if (!r.value) return;
          const body = {
            name,
            implement_type: impl.type,
            capabilities: impl.caps,
            width_m: Number(width),
            lag_s: r.value.lag_s,
            calibration: r.value.calibration,
            speed_min_m_s: Number(speedMin) / 3.6,
            speed_max_m_s: Number(speedMax) / 3.6,
          };
          create.mutate(body, {
            onSuccess: () => {
              setName('');
              setCal(EMPTY_CALIBRATION);
            },
          });
        }}
      >
        <div className="row wrap">
          <input data-testid="machine-name" placeholder="Name" value={name} onChange={(e) => setName(e.target.value)} required />
          <label className="inline">
            width m <input data-testid="machine-width" type="number" step="0.1" value={width} onChange={(e) => setWidth(e.target.value)} />
          </label>
          <label className="inline">
            speed km/h{' '}
            <input data-testid="machine-speed-min" type="number" step="0.1" value={speedMin} onChange={(e) => setSpeedMin(e.target.value)} />
            –
            <input data-testid="machine-speed-max" type="number" step="0.1" value={speedMax} onChange={(e) => setSpeedMax(e.target.value)} />
          </label>
        </div>
        <div className="row wrap" data-testid="machine-capabilities">
          <label className="inline">
            implement{' '}
            <select
              data-testid="machine-implement"
              value={impl.type}
              onChange={(e) => setImpl({ ...impl, type: e.target.value as typeof impl.type })}
            >
              <option value="spreader">spreader</option>
              <option value="seeder">seeder</option>
              <option value="seed_fertiliser_drill">seed + fertiliser drill</option>
              <option value="sprayer">sprayer</option>
            </select>
          </label>
          <label className="inline">
            <input
              data-testid="machine-depth-actuator"
              type="checkbox"
              checked={!!impl.caps.depth_actuator}
              onChange={(e) => setImpl({ ...impl, caps: { ...impl.caps, depth_actuator: e.target.checked } })}
            /> depth
            actuator
          </label>
          <label className="inline">
            <input data-testid="machine-sensor-ndvi" type="checkbox" checked={sensors.includes('canopy_ndvi')} onChange={() => toggleSensor('canopy_ndvi')} />{' '}
            canopy NDVI sensors
          </label>
          <label className="inline">
            <input data-testid="machine-sensor-depth" type="checkbox" checked={sensors.includes('depth')} onChange={() => toggleSensor('depth')} /> depth
            sensor
          </label>
        </div>
        <p className="muted small">
          Metering calibration measured on this machine (seed 001 eq. 1): q0 = a·r + b in g/min for a shaft speed r
          between min and max r/min, and the lag time from the meter to the ground.
        </p>
        <div className="row wrap">
          {FIELDS.map(([k, label, tid]) => (
            <label className="inline" key={k}>
              {label}{' '}
              <input
                data-testid={tid}
                type="number"
                step="any"
                value={cal[k]}
                aria-invalid={calErrors[k] ? true : undefined}
                onChange={(e) => setCal({ ...cal, [k]: e.target.value })}
              />
            </label>
          ))}
        </div>
        {Object.keys(calErrors).length > 0 && (
          <ul className="error" data-testid="cal-errors" role="alert">
            {Object.values(calErrors).map((m) => (
              <li key={m}>{m}</li>
            ))}
          </ul>
        )}
        {range && (
          <p className="muted small" data-testid="cal-range">
            Meters {range[0].toFixed(1)} – {range[1].toFixed(1)} kg/ha at {speedMin}–{speedMax} km/h over {width} m
            {range[0] > range[1] ? ' (no rate fits the whole speed range: narrow it)' : ''}
          </p>
        )}
        <button data-testid="machine-submit" data-write="">Add machine</button>
      </form>
      <table className="table" data-testid="machine-table">
        <thead>
          <tr>
            <th>Name</th>
            <th>Implement</th>
            <th>Width</th>
            <th>Lag</th>
            <th>Calibration</th>
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
              <td data-testid={`machine-implement-${m.id}`}>
                {m.implement_type ?? '–'}
                {m.capabilities?.depth_actuator ? ' · depth actuator' : ''}
                {((m.capabilities?.sensors as string[] | undefined) ?? []).map((x) => ` · ${x} sensor`).join('')}
              </td>
              <td>{m.width_m != null ? `${m.width_m} m` : '–'}</td>
              <td>{m.lag_s != null ? `${m.lag_s} s` : '–'}</td>
              <td data-testid={`machine-cal-${m.id}`}>{calibrationText(m.calibration)}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}
