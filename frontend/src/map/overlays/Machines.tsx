import { useMemo } from 'react';
import type { FleetMachine } from '../../lib/fleet';
import { machineLayers, machinesGeoJSON } from '../layers';
import { useLayerClick, useOverlay } from '../useOverlay';

/**
 * Machines as status-coloured dots with a heading arrow (layers `machines-dot`,
 * `machines-heading`); machines without a position are left out.
 */
export function Machines(props: {
  /** e.g. `fleet.values()` of lib/fleet; pass a stable (memoised) value to avoid redraws. */
  machines: Iterable<Pick<FleetMachine, 'machine_id' | 'lon' | 'lat' | 'heading_deg' | 'status'>>;
  /** Click on a machine: its id. */
  onClick?: (machineId: number) => void;
}) {
  const data = useMemo(() => machinesGeoJSON(props.machines), [props.machines]);
  const spec = useMemo(
    () => ({ id: 'machines', slot: 'point' as const, source: { type: 'geojson' as const, data }, layers: machineLayers() }),
    [data],
  );
  useOverlay(spec);
  const onClick = props.onClick;
  useLayerClick('machines-dot', onClick && ((f) => onClick(Number(f.properties?.machine_id))));
  return null;
}
