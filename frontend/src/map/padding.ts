/** Screen-space padding for fitting a map around what lies over it. */

export type Box = Pick<DOMRect, 'left' | 'top' | 'right' | 'bottom'>;

/**
 * Padding that keeps a fitted box out from under `cover` (an element over part of the map):
 * the covered strip on the side it covers is added to `base`. A cover beside the map (not
 * over it) adds nothing.
 */
export function visiblePadding(map: Box, cover: Box | null, base: number) {
  const pad = { top: base, bottom: base, left: base, right: base };
  if (!cover) return pad;
  const w = Math.min(map.right, cover.right) - Math.max(map.left, cover.left);
  const h = Math.min(map.bottom, cover.bottom) - Math.max(map.top, cover.top);
  if (w <= 0 || h <= 0) return pad;
  // the side the cover is attached to: a full-height panel on the left/right, a sheet below/above
  if (h >= (map.bottom - map.top) * 0.9) {
    if (cover.left <= map.left) pad.left += w;
    else pad.right += w;
  } else if (cover.bottom >= map.bottom) pad.bottom += h;
  else pad.top += h;
  return pad;
}

/**
 * Whether a point at screen position (`x`, `y`) lies outside the part of the map left
 * visible by `pad` (e.g. `visiblePadding`), shrunk by `margin` pixels on every side: a
 * followed machine is brought back into view before it reaches the edge.
 */
export function outsideVisible(
  size: { width: number; height: number },
  pad: { top: number; bottom: number; left: number; right: number },
  x: number,
  y: number,
  margin = 0,
): boolean {
  return (
    x < pad.left + margin ||
    x > size.width - pad.right - margin ||
    y < pad.top + margin ||
    y > size.height - pad.bottom - margin
  );
}
