import { describe, expect, it } from 'vitest';
import { parseApiError } from './errors';

describe('parseApiError', () => {
  it('string detail with a location', () => {
    const e = parseApiError({ detail: 'self-intersection at vertex 3', location: [10.1, 52.2] }, 422);
    expect(e.message).toBe('self-intersection at vertex 3');
    expect(e.location).toEqual([10.1, 52.2]);
  });
  it('FastAPI list detail keeps loc paths and row numbers', () => {
    const e = parseApiError(
      {
        detail: [
          { loc: ['body', 'swath_width_m'], msg: 'must be > 0' },
          { loc: ['rows', 4, 'p_mg_kg'], msg: 'not a number' },
        ],
      },
      422,
    );
    expect(e.message).toBe('2 problems');
    // the field in words, not the request's key
    expect(e.items.map((i) => i.message)).toEqual(['swath width (m): must be > 0', 'row 4: not a number']);
    expect(e.items[1].row).toBe(4);
  });
  it('object detail with row errors', () => {
    const e = parseApiError({ detail: { message: 'bad CSV', errors: [{ row: 7, reason: 'lat out of range' }] } });
    expect(e.message).toBe('bad CSV');
    expect(e.items[0].message).toBe('row 7: lat out of range');
  });
  it('Point geometry as location and plain bodies', () => {
    expect(parseApiError({ detail: 'x', location: { type: 'Point', coordinates: [1, 2] } }).location).toEqual([1, 2]);
    expect(parseApiError(null, 500).message).toBe('HTTP 500');
    expect(parseApiError('Bad Gateway', 502).message).toBe('Bad Gateway');
  });
});
