/** Thin REST client for /api/v1: bearer token from sessionStorage, errors parsed for display. */
import { parseApiError, type ParsedError } from './lib/errors';

const TOKEN_KEY = 'fieldrx.token';
const USER_KEY = 'fieldrx.user';
export const API = '/api/v1';

export class ApiError extends Error {
  readonly status: number;
  readonly parsed: ParsedError;
  /** The error body as the server sent it (e.g. the flagged cells of a 409 from POST /jobs). */
  readonly body: unknown;
  constructor(status: number, parsed: ParsedError, body?: unknown) {
    super(parsed.message);
    this.status = status;
    this.parsed = parsed;
    this.body = body;
  }
}

export function getToken(): string | null {
  return sessionStorage.getItem(TOKEN_KEY);
}

export interface SessionInfo {
  user?: { id?: number; email?: string; name?: string; role?: string } & Record<string, unknown>;
  organisation?: { id?: number; name?: string } & Record<string, unknown>;
  organisations?: { id: number; name: string }[];
}

export function getSession(): SessionInfo {
  try {
    return JSON.parse(sessionStorage.getItem(USER_KEY) ?? '{}') as SessionInfo;
  } catch {
    return {};
  }
}

export function setSession(token: string | null, info?: SessionInfo): void {
  if (token) sessionStorage.setItem(TOKEN_KEY, token);
  else sessionStorage.removeItem(TOKEN_KEY);
  if (info) sessionStorage.setItem(USER_KEY, JSON.stringify(info));
  else if (!token) sessionStorage.removeItem(USER_KEY);
}

function url(path: string): string {
  return path.startsWith('http') || path.startsWith('/api') ? path : `${API}${path}`;
}

export async function request<T = unknown>(method: string, path: string, body?: unknown): Promise<T> {
  const headers: Record<string, string> = { Accept: 'application/json' };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  let payload: BodyInit | undefined;
  if (body instanceof FormData) payload = body;
  else if (body !== undefined) {
    headers['Content-Type'] = 'application/json';
    payload = JSON.stringify(body);
  }
  const res = await fetch(url(path), { method, headers, body: payload });
  if (res.status === 401 && token) {
    setSession(null);
    window.dispatchEvent(new Event('fieldrx:logout'));
  }
  if (!res.ok) {
    const errBody = await readBody(res);
    throw new ApiError(res.status, parseApiError(errBody, res.status), errBody);
  }
  if (res.status === 204) return undefined as T;
  return (await readBody(res)) as T;
}

async function readBody(res: Response): Promise<unknown> {
  const text = await res.text();
  if (!text) return null;
  try {
    return JSON.parse(text);
  } catch {
    return text;
  }
}

export const api = {
  get: <T = unknown>(p: string) => request<T>('GET', p),
  post: <T = unknown>(p: string, b?: unknown) => request<T>('POST', p, b),
  patch: <T = unknown>(p: string, b?: unknown) => request<T>('PATCH', p, b),
  del: <T = unknown>(p: string) => request<T>('DELETE', p),
};

/** Fetches with the token and saves the response as a file (exports). */
export async function download(path: string, fallbackName: string): Promise<string> {
  const token = getToken();
  const res = await fetch(url(path), { headers: token ? { Authorization: `Bearer ${token}` } : {} });
  if (!res.ok) throw new ApiError(res.status, parseApiError(await readBody(res), res.status));
  const cd = res.headers.get('Content-Disposition') ?? '';
  const m = /filename\*?=(?:UTF-8'')?"?([^";]+)"?/i.exec(cd);
  const name = m ? decodeURIComponent(m[1]) : fallbackName;
  const blob = await res.blob();
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
  // zone exports say how they simplified the prescription: show it with the file name
  const note = res.headers.get('X-FieldRx-Export-Note');
  return note ? `${name} (${note})` : name;
}

export async function login(email: string, password: string): Promise<SessionInfo> {
  const res = await request<{ access_token: string } & SessionInfo>('POST', '/auth/login', { email, password });
  const info: SessionInfo = { user: res.user, organisation: res.organisation, organisations: res.organisations };
  setSession(res.access_token, info);
  return info;
}

export function errorText(e: unknown): string {
  if (e instanceof ApiError) {
    const extra = e.parsed.items.map((i) => i.message);
    return extra.length > 1 || (extra.length === 1 && extra[0] !== e.message)
      ? `${e.message}: ${extra.join('; ')}`
      : e.message;
  }
  return e instanceof Error ? e.message : String(e);
}

/** WebSocket URL for live updates (no token: URLs end up in access logs). */
export function liveUrl(): string {
  const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
  return `${proto}//${location.host}${API}/live`;
}

/** WebSocket subprotocols carrying the token (browsers cannot set WS headers). */
export function liveProtocols(): string[] {
  return ['fieldrx', getToken() || 'none'];
}
