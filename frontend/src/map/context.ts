/** The map of the enclosing `<MapView>`, shared with its overlay children. */
import { createContext, useContext } from 'react';
import type * as maplibregl from 'maplibre-gl';

export const MapContext = createContext<maplibregl.Map | null>(null);

/**
 * The map of the enclosing `<MapView>`, once its style has loaded (null before). Overlay
 * components read it; screens never do: they compose overlays as MapView's children.
 */
export function useMap(): maplibregl.Map | null {
  return useContext(MapContext);
}
