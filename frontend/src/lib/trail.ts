/**
 * A machine's driven trail on the live map: positions kept in time order (live messages may
 * arrive late or out of order after a reconnect or a store-and-forward backlog), drawn as
 * separate lines wherever consecutive positions are not one continuous drive: a gap in time,
 * a jump in space, or a reversal of direction between two samples (the far ends of a headland
 * turn sampled sparsely: joining them cuts diagonally across the swaths and outside the field).
 */
import { bearingDeg, distanceM, type Position } from './geo';

export interface TrailPoint {
  lon: number;
  lat: number;
  /** record time, seconds */
  t: number;
}

/** Longest time between two samples of one drive. */
export const TRAIL_GAP_S = 10;
/** Longest step between two samples of one drive (a 12 m swath over a short gap). */
export const TRAIL_JUMP_M = 30;
/** Largest change of travel direction between two consecutive steps of one drive. */
export const TRAIL_TURN_DEG = 100;
/** Largest change of travel direction over two steps of one drive (a sparsely sampled U-turn). */
export const TRAIL_REVERSE_DEG = 150;

/** Add `p` to `trail` (in place) at its place in time; a repeat of a known time is ignored; keeps the last `max`. */
export function addTrailPoint(trail: TrailPoint[], p: TrailPoint, max: number): void {
  let i = trail.length;
  while (i > 0 && trail[i - 1].t > p.t) i--;
  if (i > 0 && trail[i - 1].t === p.t) return;
  trail.splice(i, 0, p);
  if (trail.length > max) trail.splice(0, trail.length - max);
}

function turn(a: number, b: number): number {
  const d = Math.abs(a - b) % 360;
  return d > 180 ? 360 - d : d;
}

/** The trail as lines: a new line wherever the drive was not continuous (see module doc). */
export function trailSegments(trail: readonly TrailPoint[]): Position[][] {
  const out: Position[][] = [];
  let cur: Position[] = [];
  // travel direction of the last two steps of the current line (null: none yet)
  let b1: number | null = null;
  let b2: number | null = null;
  const cut = (keep: Position[]) => {
    if (cur.length > 1) out.push(cur);
    cur = keep;
    b1 = b2 = null;
  };
  for (let i = 0; i < trail.length; i++) {
    const p: Position = [trail[i].lon, trail[i].lat];
    if (i > 0) {
      const q = trail[i - 1];
      const prev: Position = [q.lon, q.lat];
      const step = distanceM(prev, p);
      const b: number | null = step > 0.5 ? bearingDeg(prev, p) : b1;
      if (trail[i].t - q.t > TRAIL_GAP_S || step > TRAIL_JUMP_M || (b != null && b1 != null && turn(b, b1) > TRAIL_TURN_DEG)) {
        cut([]);
      } else if (b != null && b2 != null && turn(b, b2) > TRAIL_REVERSE_DEG) {
        // a U-turn in two samples: the step between them crossed from one pass to the next
        const joint = cur.pop() as Position;
        cut([joint]);
        b1 = b;
      } else {
        b2 = b1;
        b1 = b;
      }
    }
    cur.push(p);
  }
  cut([]);
  return out;
}
