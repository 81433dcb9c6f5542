import { useEffect, useState } from 'react';
import { ApiError, call, client, type Schemas } from '../api/client';
import { useJobKinds, useSendableMachines } from '../api/hooks';
import { meterableRange, type LinearCalibration } from '../lib/calibration';
import { flaggedConfirmation } from '../lib/flags';
import { kindList, kindsTaking } from '../lib/jobkinds';
import { outsideMeter } from '../lib/rxform';
import { formatRate } from '../lib/units';
import { navigate } from '../router';
import { ErrorBox } from './Status';

/**
 * Send the version on screen to a machine: the chosen machine's meterable range at its
 * speed range (seed 001 eq. 1-3) beside the version's rate range, with a warning when rates
 * fall outside; a 409 naming flagged cells asks for confirmation, then resends. Only the
 * job kinds that take the prescription's rate unit are offered (GET /jobs/kinds).
 */
export function SendJobPanel(props: { rxId: number; version: number | null; summary: Schemas['RxSummary'] | null | undefined; rateUnit?: string }) {
  const { rxId, version, summary, rateUnit } = props;
  const kinds = useJobKinds().data?.kinds;
  // while the kinds or the unit are not known, the server's default kind
  const taking = kinds && rateUnit ? kindsTaking(kinds, rateUnit) : null;
  const [chosenKind, setKind] = useState('');
  const kind = taking?.find((k) => k.name === chosenKind)?.name ?? taking?.[0]?.name;
  const cellsKinds = kindList(kinds).filter((k) => k.rates_from === 'cells');
  const machines = useSendableMachines();
  const items = machines.data?.items ?? [];
  const [machineId, setMachineId] = useState('');
  const [confirm, setConfirm] = useState<{ message: string; count: number; areaM2: number; seq: number[] } | null>(null);
  const [error, setError] = useState<unknown>(null);
  useEffect(() => {
    if (!machineId && items[0]) setMachineId(String(items[0].id));
  }, [items, machineId]);
  const m = items.find((x) => String(x.id) === machineId);
  const cal = m?.calibration as Partial<LinearCalibration> | undefined;
  const range =
    m && cal?.slope_g_min_per_rpm != null && cal.min_rpm != null
      ? meterableRange(cal as LinearCalibration, m.width_m, m.speed_min_m_s, m.speed_max_m_s)
      : null;
  const outside = range && summary ? outsideMeter(summary, range[0], range[1]) : null;
  const send = async (confirmFlagged: boolean) => {
    setError(null);
    try {
      const j = await call(
        client.POST('/api/v1/jobs', {
          body: {
            kind: kind as Schemas['JobIn']['kind'],
            prescription_id: rxId,
            prescription_version: version ?? undefined,
            machine_id: Number(machineId),
            confirm_flagged: confirmFlagged,
          },
        }),
      );
      setConfirm(null);
      // A new job is 'planned'; sending makes it downloadable by the machine.
      if (j.state === 'planned') await call(client.POST('/api/v1/jobs/{job_id}/state', { params: { path: { job_id: j.id } }, body: { state: 'sent' } }));
      navigate(`/jobs?created=${j.id}`);
    } catch (e) {
      const c = e instanceof ApiError ? flaggedConfirmation(e.status, e.body) : null;
      if (c) setConfirm(c);
      else setError(e);
    }
  };
  return (
    <div data-testid="send-job-panel">
      {taking && taking.length > 1 && (
        <label>
          Job kind{' '}
          <select data-testid="send-job-kind" value={kind} onChange={(e) => setKind(e.target.value)}>
            {taking.map((k) => (
              <option key={k.name} value={k.name}>
                {k.label}
              </option>
            ))}
          </select>
        </label>
      )}
      {taking && taking.length === 0 && (
        <p className="warn" data-testid="send-job-unit">
          No job kind takes a prescription in {rateUnit}: {cellsKinds.map((k) => `${k.label} takes ${k.rate_units.join(', ') || 'none'}`).join('; ')}.
        </p>
      )}
      <div className="row">
        <select data-testid="job-machine" value={machineId} onChange={(e) => setMachineId(e.target.value)}>
          {items.map((x) => (
            <option key={x.id} value={x.id}>
              {x.name}
            </option>
          ))}
        </select>
        <button data-testid="send-job" data-write="" disabled={!machineId || taking?.length === 0} onClick={() => void send(false)}>
          Send job (v{version ?? '–'})
        </button>
      </div>
      {range && m && (
        <div className="small" data-testid="job-machine-range">
          Meters {formatRate(range[0])} – {formatRate(range[1])} at {(m.speed_min_m_s * 3.6).toFixed(1)}–{(m.speed_max_m_s * 3.6).toFixed(1)} km/h;
          this version: {formatRate(summary?.rate_min_kg_ha)} – {formatRate(summary?.rate_max_kg_ha)}
          {outside ? (
            <div className="warn" data-testid="job-machine-warn">
              Outside the machine's range: {outside}.
            </div>
          ) : (
            <span className="ok"> · within range</span>
          )}
        </div>
      )}
      <ErrorBox error={error} testid="send-job-error" />
      {confirm && (
        <div className="card warn" data-testid="job-confirm-panel" role="alertdialog">
          <p data-testid="job-confirm-text">{confirm.message}</p>
          <p className="small">
            Cells: {confirm.seq.slice(0, 30).join(', ')}
            {confirm.count > 30 ? ' …' : ''}
          </p>
          <div className="row">
            <button data-testid="job-confirm" data-write="" className="danger" onClick={() => void send(true)}>
              Send anyway ({confirm.count} flagged)
            </button>
            <button data-testid="job-confirm-cancel" onClick={() => setConfirm(null)}>
              Cancel
            </button>
          </div>
        </div>
      )}
    </div>
  );
}
