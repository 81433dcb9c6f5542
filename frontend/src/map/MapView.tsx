import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client } from '../api/client';
import { ImageryControl } from '../components/ImageryControl';
import { bboxOf } from '../lib/geo';
import { startBounds } from '../lib/imagery';
import { createMap, fitTo } from './setup';

/**
 * A map that lives as long as the component. onReady runs once after 'load'
 * so screens add sources/layers in one place.
 *
 * Every map opens fitted to the organisation's fields (never at world zoom) unless the
 * screen has already moved it to its own content, and carries the imagery control: the
 * newest orthophoto of ``fieldId`` (or the organisation's imagery) under all data layers.
 */
export function MapView(props: {
  name: string;
  onReady?: (map: maplibregl.Map) => void | (() => void);
  className?: string;
  children?: React.ReactNode;
  fieldId?: number;
  imagery?: boolean;
}) {
  const ref = useRef<HTMLDivElement>(null);
  const [map, setMap] = useState<maplibregl.Map | null>(null);
  const readyRef = useRef(props.onReady);
  readyRef.current = props.onReady;
  useEffect(() => {
    if (!ref.current) return;
    const map = createMap(ref.current, props.name);
    let cleanup: void | (() => void);
    let moved = false;
    let alive = true;
    map.once('movestart', () => {
      moved = true;
    });
    map.on('load', () => {
      cleanup = readyRef.current?.(map);
      setMap(map);
      call(client.GET('/api/v1/fields', { params: { query: { limit: 1000 } } }))
        .then((fc) => {
          const b = startBounds(bboxOf(fc));
          if (alive && !moved && b) fitTo(map, b, 40);
        })
        .catch(() => undefined);
    });
    return () => {
      alive = false;
      if (typeof cleanup === 'function') cleanup();
      map.remove();
    };
  }, [props.name]);
  return (
    <div className={`map-wrap ${props.className ?? ''}`}>
      <div ref={ref} className="map" data-testid={`map-${props.name}`} />
      {props.imagery !== false && <ImageryControl map={map} fieldId={props.fieldId} />}
      {props.children}
    </div>
  );
}
