/**
 * The browser's REST client: openapi-fetch over the types generated from the server's
 * OpenAPI document (src/api/generated/schema.ts, `scripts/gen-api.sh`). Paths, query
 * parameters, bodies and answers are checked by the compiler against the server's
 * models; nothing here guesses at a field name.
 */
import createClient, { type Middleware } from 'openapi-fetch';
import { parseApiError, type ParsedError } from '../lib/errors';
import type { components, paths } from './generated/schema';

const TOKEN_KEY = 'fieldrx.token';
const USER_KEY = 'fieldrx.user';
export const API = '/api/v1';

/** The server's models by name (e.g. `Schemas['PrescriptionOut']`). */
export type Schemas = components['schemas'];
export type FieldFeature = Schemas['FieldFeature'];
export type Farm = Schemas['FarmOut'];
export type Machine = Schemas['MachineOut'];
export type Plan = Schemas['PlanOut'];
export type Prescription = Schemas['PrescriptionOut'];
export type Job = Schemas['JobOut'];
export type MachineStatus = Schemas['MachineStatus'];
export type AlertGroup = Schemas['AlertGroup'];
export type ImageryItem = Schemas['ImageryOut'];
export type ErrorBody = Schemas['ErrorOut'];

export class ApiError extends Error {
  readonly status: number;
  readonly parsed: ParsedError;
  /** The error body as the server sent it (`ErrorOut`, e.g. the flagged cells of a 409). */
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

/** Who is signed in (the login answer without its token). */
export type SessionInfo = Partial<Pick<Schemas['LoginOut'], 'user' | 'organisation' | 'organisations'>>;

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

const auth: Middleware = {
  onRequest({ request }) {
    const token = getToken();
    if (token) request.headers.set('Authorization', `Bearer ${token}`);
    return request;
  },
  onResponse({ response }) {
    if (response.status === 401 && getToken()) {
      setSession(null);
      window.dispatchEvent(new Event('fieldrx:logout'));
    }
    return response;
  },
};

/** Typed calls: `client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id } } })`. */
export const client = createClient<paths>({ baseUrl: location.origin });
client.use(auth);

/** The answer's data, or an `ApiError` carrying the server's `ErrorOut`. */
export async function call<T>(
  pending: Promise<{ data?: T; error?: unknown; response: Response }>,
): Promise<NonNullable<T>> {
  const { data, error, response } = await pending;
  if (!response.ok) throw new ApiError(response.status, parseApiError(error, response.status), error);
  return data as NonNullable<T>;
}

/** A multipart body for an upload route (openapi-fetch sends FormData as it is). */
export function formBody(fd: FormData): { body: never; bodySerializer: () => FormData } {
  return { body: {} as never, bodySerializer: () => fd };
}

/** Fetches with the token and saves the response as a file (exports). */
export async function download(path: string, fallbackName: string): Promise<string> {
  const res = await fetchFile(path);
  return saveFile(res, fallbackName);
}

async function fetchFile(path: string): Promise<Response> {
  const token = getToken();
  const res = await fetch(path.startsWith('/api') ? path : `${API}${path}`, {
    headers: token ? { Authorization: `Bearer ${token}` } : {},
  });
  if (!res.ok) {
    const text = await res.text();
    let body: unknown = text;
    try {
      body = JSON.parse(text);
    } catch {
      /* not JSON: the text is the message */
    }
    throw new ApiError(res.status, parseApiError(body, res.status), body);
  }
  return res;
}

/**
 * An export that the server may queue (large jobs: 202 with an ``export`` task): the file is
 * saved at once (``{ file }``), or the task is returned (``{ task }``) for the caller to
 * follow; its ``result_url`` is then passed to ``download``.
 */
export async function downloadOrTask(
  path: string,
  fallbackName: string,
): Promise<{ file: string } | { task: Schemas['TaskOut'] }> {
  const res = await fetchFile(path);
  if (res.status === 202) return { task: (await res.json()) as Schemas['TaskOut'] };
  return { file: await saveFile(res, fallbackName) };
}

async function saveFile(res: Response, fallbackName: string): Promise<string> {
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
  const res = await call(client.POST('/api/v1/auth/login', { body: { email, password } }));
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

/**
 * The answer of a route that queues the work when asked to (``?background=true``: 202 with
 * a task) read as the inline result the UI asked for; a task answer here is a bug, said so.
 */
export function inline<T extends object>(data: T | Schemas['TaskOut']): T {
  if ('url' in data && typeof data.url === 'string' && data.url.includes('/tasks/')) {
    throw new Error(`the server queued this as task ${data.url}; expected the result inline`);
  }
  return data as T;
}
