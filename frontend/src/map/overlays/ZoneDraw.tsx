import { useEffect, useRef } from 'react';
import { TerraDraw, TerraDrawPolygonMode, TerraDrawSelectMode } from 'terra-draw';
import { TerraDrawMapLibreGLAdapter } from 'terra-draw-maplibre-gl-adapter';
import { useMap } from '../context';

export type DrawMode = 'polygon' | 'select' | 'static';

declare global {
  interface Window {
    /** The live drawing tool, for end-to-end tests. */
    __fieldrxDraw?: TerraDraw;
  }
}

/**
 * Polygon drawing (terra-draw) on the enclosing map: boundaries, holes, rate zones. The tool
 * lives as long as the component; `mode` switches it (the screen's state decides). The
 * screen reads and edits features through the instance handed to `onReady` / the events
 * (`draw.getSnapshot()`, `addFeatures`, `removeFeatures`, `clear`, `selectFeature`).
 */
export function ZoneDraw(props: {
  /** 'polygon' draws, 'select' drags vertices (only with `editable`), 'static' leaves the map alone. */
  mode: DrawMode;
  /** Offer the select mode: drag the polygon, its corners and midpoints; delete corners. */
  editable?: boolean;
  /** Called once the tool has started (load existing features here). */
  onReady?: (draw: TerraDraw) => void;
  /** Any feature changed (also while drawing). */
  onChange?: (draw: TerraDraw) => void;
  /** A polygon was closed (or an edit finished): its id. */
  onFinish?: (id: string | number, draw: TerraDraw) => void;
}) {
  const map = useMap();
  const drawRef = useRef<TerraDraw | null>(null);
  const cbs = useRef(props);
  cbs.current = props;
  const editable = props.editable ?? false;
  useEffect(() => {
    if (!map) return;
    const modes = [new TerraDrawPolygonMode()] as ConstructorParameters<typeof TerraDraw>[0]['modes'];
    if (editable)
      modes.push(
        new TerraDrawSelectMode({
          flags: {
            polygon: { feature: { draggable: true, coordinates: { midpoints: true, draggable: true, deletable: true } } },
          },
        }),
      );
    const draw = new TerraDraw({ adapter: new TerraDrawMapLibreGLAdapter({ map }), modes });
    draw.start();
    draw.setMode(cbs.current.mode);
    draw.on('change', () => cbs.current.onChange?.(draw));
    draw.on('finish', (id) => cbs.current.onFinish?.(id, draw));
    drawRef.current = draw;
    window.__fieldrxDraw = draw;
    cbs.current.onReady?.(draw);
    return () => {
      drawRef.current = null;
      if (window.__fieldrxDraw === draw) window.__fieldrxDraw = undefined;
      try {
        draw.stop();
      } catch {
        /* map already gone */
      }
    };
  }, [map, editable]);
  const { mode } = props;
  useEffect(() => {
    const draw = drawRef.current;
    if (draw && draw.getMode() !== mode) draw.setMode(mode);
  }, [mode, map]);
  return null;
}
