import { useEffect, useRef, useState } from 'react';
import { liveProtocols, liveUrl } from './api/client';

export interface LiveMessage {
  type: 'position' | 'status' | 'alert' | string;
  machine_id?: number;
  [k: string]: unknown;
}

/**
 * Subscribes to /api/v1/live; reconnects with back-off so a server restart
 * does not leave the fleet map frozen. Returns the connection state.
 */
export function useLive(onMessage: (m: LiveMessage) => void): 'connecting' | 'open' | 'closed' {
  const [state, setState] = useState<'connecting' | 'open' | 'closed'>('connecting');
  const cb = useRef(onMessage);
  cb.current = onMessage;
  useEffect(() => {
    let ws: WebSocket | null = null;
    let stopped = false;
    let delay = 500;
    let timer: ReturnType<typeof setTimeout> | undefined;
    const connect = () => {
      setState('connecting');
      ws = new WebSocket(liveUrl(), liveProtocols());
      ws.onopen = () => {
        delay = 500;
        setState('open');
      };
      ws.onmessage = (ev) => {
        try {
          const data = JSON.parse(String(ev.data)) as LiveMessage | LiveMessage[];
          for (const m of Array.isArray(data) ? data : [data]) cb.current(m);
        } catch {
          /* ignore non-JSON keep-alives */
        }
      };
      ws.onclose = () => {
        setState('closed');
        if (!stopped) timer = setTimeout(connect, (delay = Math.min(delay * 2, 10_000)));
      };
    };
    connect();
    return () => {
      stopped = true;
      clearTimeout(timer);
      ws?.close();
    };
  }, []);
  return state;
}
