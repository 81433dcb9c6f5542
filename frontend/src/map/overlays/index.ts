/**
 * Map overlays: each adds its own sources and layers to the enclosing `<MapView>` on mount,
 * updates them when its props change and removes them on unmount. Screens compose them;
 * no screen calls addLayer / addSource itself (src/screens/noDirectMap.test.ts).
 */
export { CellGrid } from './CellGrid';
export { FieldBoundary } from './FieldBoundary';
export { FitBounds } from './FitBounds';
export { Follow } from './Follow';
export { Holes } from './Holes';
export { Imagery, IMAGERY_ID } from './Imagery';
export { Machines } from './Machines';
export { Points } from './Points';
export { Problems } from './Problems';
export { Track, type TrackHead } from './Track';
export { ZoneDraw, type DrawMode } from './ZoneDraw';
