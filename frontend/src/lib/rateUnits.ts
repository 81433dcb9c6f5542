import registry from '../api/generated/rate-units.json';

/**
 * The rate units a prescription can go to machines in (edge_agent/fieldrx_edge/rateunits,
 * written to generated/rate-units.json by scripts/gen-api.sh): the prescription form's unit
 * menu and its lot inputs read them here, so a unit added on the server needs no edit here.
 * The server works every rate out in kg/ha of product; a unit converts through values of
 * the product lot (a liquid's density, ...) and the server says how many kg/ha one unit is
 * (kg_per_unit).
 */
export interface LotValueInfo {
  /** the product's field and the request's lot key */
  key: string;
  label: string;
  unit: string;
  /** plausible range, inclusive */
  min: number;
  max: number;
}

export interface RateUnitInfo {
  name: string;
  label: string;
  quantity: string;
  lot: LotValueInfo[];
  /** the unit counts seeds: its product is a seed lot named by the user, not a fertiliser */
  seed_lot?: boolean;
}

export const RATE_UNITS: RateUnitInfo[] = registry.rate_units;

/** The unit the server works in and stores (the registry lists it first). */
export const BASE_UNIT: string = RATE_UNITS[0]?.name ?? 'kg/ha';

export function rateUnit(name: string | null | undefined): RateUnitInfo | undefined {
  return RATE_UNITS.find((u) => u.name === (name || BASE_UNIT));
}

/** Every lot value any unit converts through (one product field each). */
export const LOT_VALUES: LotValueInfo[] = RATE_UNITS.flatMap((u) => u.lot).filter((v, i, all) => all.findIndex((w) => w.key === v.key) === i);
