import { useState } from 'react';
import { call, client, type Plan, type Schemas, inline } from '../api/client';
import { qk, useApiMutation } from '../api/hooks';
import { ErrorBox } from '../components/Status';
import { serverDefault } from '../api/defaults';

/** Planning parameters (metres, degrees); the server validates and returns 422 with the field name. */
export function PlanForm({ fieldId, onCreated }: { fieldId: number; onCreated: (p: Plan) => void }) {
  const [swath, setSwath] = useState('2.3'); // seed 001's implement width
  const [cell, setCell] = useState('5'); // seed 001: L >= v_max * T_lag = 3.8 m
  const [rule, setRule] = useState('longest_edge');
  const [heading, setHeading] = useState('0');
  const [headland, setHeadland] = useState(String(serverDefault('PlanIn', 'headland_passes')));
  const [radius, setRadius] = useState(String(serverDefault('PlanIn', 'turn_radius_m')));
  const [reverse, setReverse] = useState(serverDefault('PlanIn', 'reverse'));
  const [pattern, setPattern] = useState<string>(serverDefault('PlanIn', 'pattern'));
  const create = useApiMutation(
    (body: Schemas['PlanIn']) =>
      call(client.POST('/api/v1/fields/{field_id}/plans', { params: { path: { field_id: fieldId } }, body })).then(inline),
    { invalidate: () => [qk.fieldPlans(fieldId)] },
  );
  return (
    <form
      className="form"
      data-testid="plan-form" data-write=""
      onSubmit={(e) => {
        e.preventDefault();
        const body: Schemas['PlanIn'] = {
          swath_width_m: Number(swath),
          cell_length_m: Number(cell),
          heading: rule as Schemas['PlanIn']['heading'],
          headland_passes: Number(headland),
          angle_deg: rule === 'angle' ? Number(heading) : undefined,
          turn_radius_m: Number(radius),
          reverse,
          pattern: pattern as Schemas['PlanIn']['pattern'],
        };
        create.mutate(body, { onSuccess: onCreated });
      }}
    >
      <h4>New plan</h4>
      <label>
        Swath width (m)
        <input data-testid="plan-swath" type="number" step="0.1" min="0" value={swath} onChange={(e) => setSwath(e.target.value)} />
      </label>
      <label>
        Cell length (m)
        <input data-testid="plan-cell" type="number" step="0.1" min="0" value={cell} onChange={(e) => setCell(e.target.value)} />
      </label>
      <label>
        Heading rule
        <select data-testid="plan-heading-rule" value={rule} onChange={(e) => setRule(e.target.value)}>
          <option value="longest_edge">Parallel to the longest edge</option>
          <option value="optimal">Optimal (fewest turns)</option>
          <option value="angle">Fixed heading</option>
        </select>
      </label>
      {rule === 'angle' && (
        <label>
          Heading (° from north)
          <input data-testid="plan-heading" type="number" value={heading} onChange={(e) => setHeading(e.target.value)} />
        </label>
      )}
      <label>
        Headland passes
        <input
          data-testid="plan-headland"
          type="number"
          min="0"
          step="1"
          value={headland}
          onChange={(e) => setHeadland(e.target.value)}
        />
      </label>
      <label title="The machine's minimum turning radius: turns and headland rings never curve tighter">
        Turning radius (m)
        <input
          data-testid="plan-turn-radius"
          name="turn_radius_m"
          type="number"
          step="0.5"
          min="0"
          value={radius}
          onChange={(e) => setRadius(e.target.value)}
        />
      </label>
      <label>
        <input data-testid="plan-reverse" type="checkbox" checked={reverse} onChange={(e) => setReverse(e.target.checked)} />{' '}
        Machine may reverse (K-turns)
      </label>
      <label>
        Swath order
        <select data-testid="plan-pattern" value={pattern} onChange={(e) => setPattern(e.target.value)}>
          <option value="boustrophedon">Back and forth</option>
          <option value="skip">Skip rows (U-turns only)</option>
          <option value="auto">Whichever turns faster</option>
        </select>
      </label>
      <button data-testid="plan-submit" disabled={create.isPending}>
        {create.isPending ? 'Planning…' : 'Plan coverage'}
      </button>
      <ErrorBox error={create.error} testid="plan-error" />
    </form>
  );
}
