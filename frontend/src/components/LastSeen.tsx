import { useEffect, useState } from 'react';
import { lastSeenText } from '../lib/fleet';

/** Ticks every `ms` so "… ago" texts stay true without the screen re-rendering. */
export function useNow(ms = 5000): number {
  const [now, setNow] = useState(Date.now());
  useEffect(() => {
    const t = setInterval(() => setNow(Date.now()), ms);
    return () => clearInterval(t);
  }, [ms]);
  return now;
}

/** "offline · last seen 5 min ago" / "last seen just now", with the exact time as a tooltip. */
export function LastSeen(props: { seenMs?: number | null; online?: boolean; testid?: string }) {
  const now = useNow();
  const { seenMs, online } = props;
  return (
    <span
      className="last-seen"
      data-testid={props.testid}
      title={seenMs != null ? new Date(seenMs).toLocaleString() : undefined}
    >
      {online === false && <strong>offline · </strong>}
      {seenMs == null ? 'no data yet' : `last seen ${lastSeenText(seenMs, now)}`}
    </span>
  );
}
