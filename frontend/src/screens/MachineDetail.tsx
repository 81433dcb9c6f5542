import { useCallback, useEffect, useMemo, useState } from 'react';
import { call, client, type Machine } from '../api/client';
import { qk, useInvalidate, useMachine } from '../api/hooks';
import { ErrorBox, Kv } from '../components/Status';
import { Busy, useBusy } from '../components/Busy';
import { TimeChart } from '../components/TimeChart';
import { decimate, normaliseTrack, type TrackPoint } from '../lib/track';
import { formatSpeed, msToKmh } from '../lib/units';
import { useLive } from '../live';
import { calibrationText } from '../lib/calibration';
import { CalibrationEditor, DeviceToken } from '../components/MachineForms';
import { RouteHistory } from '../components/RouteHistory';

const MAX_POINTS = 3000;

/** One machine: settings, device token, raw vs filtered speed and target vs actual shaft speed. */
export function MachineDetail({ machineId }: { machineId: number }) {
  const machineQ = useMachine(machineId);
  const machine: Machine | null = machineQ.data ?? null;
  const refresh = useInvalidate();
  const [track, setTrack] = useState<TrackPoint[]>([]);
  const [error, setError] = useState<unknown>(null);

  const { busy, run } = useBusy();

  const loadTrack = useCallback(async () => {
    try {
      // The newest records: ask for the total first, then the last page (time order).
      const path = { machine_id: machineId };
      const head = await call(client.GET('/api/v1/machines/{machine_id}/track', { params: { path, query: { limit: 1 } } }));
      const limit = 10_000;
      const offset = Math.max(0, head.total - limit);
      const page = await call(client.GET('/api/v1/machines/{machine_id}/track', { params: { path, query: { limit, offset } } }));
      setTrack(normaliseTrack(page));
    } catch (e) {
      setError(e);
    }
  }, [machineId]);

  useEffect(() => {
    void run(loadTrack);
  }, [machineId, loadTrack, run]);

  useLive((m) => {
    if (Number(m.machine_id) !== machineId || m.type !== 'position') return;
    const p = normaliseTrack([{ ...m, speed_filtered_m_s: m.speed_filtered_m_s ?? m.speed_m_s }]);
    if (p.length) setTrack((cur) => [...cur, ...p].slice(-20000));
  });

  const d = useMemo(() => decimate(track, MAX_POINTS), [track]);
  const t = useMemo(() => d.map((p) => p.t), [d]);
  const speed = useMemo(
    () => [
      { label: 'raw (km/h)', values: d.map((p) => (p.speed_raw_m_s == null ? null : msToKmh(p.speed_raw_m_s))), color: '#bbbbbb' },
      {
        label: 'filtered (km/h)',
        values: d.map((p) => (p.speed_filtered_m_s == null ? null : msToKmh(p.speed_filtered_m_s))),
        color: '#1e3a8a',
      },
    ],
    [d],
  );
  const shaft = useMemo(
    () => [
      { label: 'target (r/min)', values: d.map((p) => p.target_shaft_rpm), color: '#d7263d', dash: [6, 4] },
      { label: 'actual (r/min)', values: d.map((p) => p.actual_shaft_rpm), color: '#2e9e44' },
    ],
    [d],
  );
  const last = track[track.length - 1];
  const hasRaw = track.some((p) => p.speed_raw_m_s != null);
  const hasShaft = track.some((p) => p.target_shaft_rpm != null || p.actual_shaft_rpm != null);

  return (
    <div className="page">
      <p>
        <a href="#/fleet">← Fleet</a>
      </p>
      <h2 data-testid="machine-title">{machine?.name ?? `Machine #${machineId}`}</h2>
      <Busy busy={busy} label="loading the latest records…" testid="machine-busy" />
      <ErrorBox error={error ?? machineQ.error} />
      <Kv
        items={[
          ['Implement', String(machine?.implement_type ?? '–')],
          ['Width', machine?.width_m != null ? `${machine.width_m} m` : '–'],
          ['Lag', machine?.lag_s != null ? `${machine.lag_s} s` : '–'],
          ['Calibration', calibrationText(machine?.calibration), 'machine-calibration'],
          ['Last speed', formatSpeed(last?.speed_filtered_m_s), 'machine-last-speed'],
          ['Track points', String(track.length), 'machine-track-count'],
        ]}
      />
      <CalibrationEditor machine={machine} onSaved={() => void refresh(qk.machine(machineId), qk.machines())} />
      <DeviceToken machineId={machineId} />
      <RouteHistory machineId={machineId} />
      <TimeChart t={t} series={speed} title="Ground speed: raw vs Kalman-filtered" unit="km/h" testid="chart-speed" />
      {track.length > 0 && !hasRaw && (
        <p className="muted small" data-testid="chart-speed-note">
          The server's track has no raw GNSS speed yet: only the filtered speed is drawn.
        </p>
      )}
      <TimeChart t={t} series={shaft} title="Metering shaft: target vs actual" unit="r/min" testid="chart-shaft" />
      {track.length > 0 && !hasShaft && (
        <p className="muted small" data-testid="chart-shaft-note">
          The server's track has no shaft speeds yet.
        </p>
      )}
    </div>
  );
}
