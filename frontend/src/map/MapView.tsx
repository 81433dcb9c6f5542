import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { createMap } from './setup';

/**
 * A map that lives as long as the component. onReady runs once after 'load'
 * so screens add sources/layers in one place.
 */
export function MapView(props: {
  name: string;
  onReady?: (map: maplibregl.Map) => void | (() => void);
  className?: string;
  children?: React.ReactNode;
}) {
  const ref = useRef<HTMLDivElement>(null);
  const [, setMap] = useState<maplibregl.Map | null>(null);
  const readyRef = useRef(props.onReady);
  readyRef.current = props.onReady;
  useEffect(() => {
    if (!ref.current) return;
    const map = createMap(ref.current, props.name);
    let cleanup: void | (() => void);
    map.on('load', () => {
      cleanup = readyRef.current?.(map);
      setMap(map);
    });
    return () => {
      if (typeof cleanup === 'function') cleanup();
      map.remove();
    };
  }, [props.name]);
  return (
    <div className={`map-wrap ${props.className ?? ''}`}>
      <div ref={ref} className="map" data-testid={`map-${props.name}`} />
      {props.children}
    </div>
  );
}
