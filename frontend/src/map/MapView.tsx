import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { useFields } from '../api/hooks';
import { ImageryControl } from '../components/ImageryControl';
import { bboxOf } from '../lib/geo';
import { startBounds } from '../lib/imagery';
import { MapContext, useMap } from './context';
import { addSlotAnchors } from './overlay';
import { createMap, fitTo } from './setup';

export { useMap };

/**
 * The one map component. Owns the maplibre map for as long as it is
 * mounted, registers it as `window.__fieldrxMaps[name]` (the browser tests read it), and
 * hands it to its children through context once loaded. Screens compose overlays:
 *
 * ```tsx
 * <MapView name="plan" fieldId={field?.id}>
 *   <FieldBoundary data={field} fill={false} />
 *   <CellGrid id="grid" tiles={planTilesUrl(planId)} />
 *   <Track id="route" data={route} arrows />
 *   <FitBounds bbox={bboxOf(field)} />
 * </MapView>
 * ```
 *
 * Every map opens fitted to the organisation's fields (never at world zoom) unless something
 * has already moved it (e.g. a `FitBounds`), and carries the imagery control: the newest
 * orthophoto of `fieldId` (or the organisation's imagery) under all data layers.
 */
export function MapView(props: {
  /** Registry name (`window.__fieldrxMaps[name]`, `data-testid="map-<name>"`). */
  name: string;
  className?: string;
  /** Overlays (render nothing themselves) and any floating controls over the map. */
  children?: React.ReactNode;
  /** The field whose imagery the imagery control offers first. */
  fieldId?: number;
  /** false hides the imagery control (default shown). */
  imagery?: boolean;
}) {
  const ref = useRef<HTMLDivElement>(null);
  const [map, setMap] = useState<maplibregl.Map | null>(null);
  const movedRef = useRef(false);
  useEffect(() => {
    if (!ref.current) return;
    const m = createMap(ref.current, props.name);
    movedRef.current = false;
    m.once('movestart', () => {
      movedRef.current = true;
    });
    m.on('load', () => {
      addSlotAnchors(m);
      setMap(m);
    });
    return () => {
      setMap(null);
      m.remove();
    };
  }, [props.name]);

  // A panel floating over the map (cab tablet, phone: .split > .panel is absolutely placed)
  // hides part of it: the map's padding keeps centre and fitted bounds in the visible part.
  useEffect(() => {
    const box = ref.current;
    if (!map || !box) return;
    const panel = box.closest('.split')?.querySelector<HTMLElement>(':scope > .panel');
    const update = () => {
      const pad = { top: 0, right: 0, bottom: 0, left: 0 };
      if (panel && getComputedStyle(panel).position === 'absolute' && panel.offsetParent) {
        const m = box.getBoundingClientRect();
        const p = panel.getBoundingClientRect();
        // a side panel covers the left edge; a bottom sheet covers the lower edge
        if (p.width < m.width * 0.9) pad.left = Math.max(0, Math.min(p.right - m.left, m.width * 0.8));
        else pad.bottom = Math.max(0, Math.min(m.bottom - p.top, m.height * 0.8));
      }
      map.setPadding(pad);
    };
    update();
    const ro = new ResizeObserver(update);
    ro.observe(box);
    if (panel) ro.observe(panel);
    window.addEventListener('resize', update);
    return () => {
      ro.disconnect();
      window.removeEventListener('resize', update);
    };
  }, [map]);

  // The organisation's extent as the opening view (the same cached query as the Fields screen's).
  const orgFields = useFields({ limit: 500 });
  useEffect(() => {
    if (!map || movedRef.current || !orgFields.data) return;
    const b = startBounds(bboxOf(orgFields.data));
    if (b) fitTo(map, b, 40);
  }, [map, orgFields.data]);

  return (
    <div className={`map-wrap ${props.className ?? ''}`}>
      <div ref={ref} className="map" data-testid={`map-${props.name}`} />
      <MapContext.Provider value={map}>
        {props.imagery !== false && <ImageryControl fieldId={props.fieldId} />}
        {props.children}
      </MapContext.Provider>
    </div>
  );
}
