/**
 * One data hook per resource, on TanStack Query: every screen that shows a
 * resource reads it through the same cache key, so a field loaded on Fields is not fetched
 * again on the plan screen, polling is a hook option instead of a setInterval per screen, and
 * an edit refetches exactly what it changed (`useApiMutation(..., { invalidate })`).
 *
 * Keys (`qk`) are hierarchical so a prefix invalidates a resource and everything under it:
 * `qk.field(7)` = ['fields', 7] covers its plans, soil samples and imagery; `qk.fields()` =
 * ['fields', 'list'] covers every filtered list.
 *
 * ```ts
 * const field = useField(fieldId);                      // field.data, field.error, field.isPending
 * const jobs = useJobs({}, { refetchInterval: 5000 });  // polled
 * const save = useApiMutation(
 *   (body: Schemas['FarmIn']) => call(client.POST('/api/v1/farms', { body })),
 *   { invalidate: () => [qk.farms()] },
 * );
 * save.mutate(body); // save.error, save.isPending
 * ```
 */
import {
  keepPreviousData,
  QueryClient,
  queryOptions,
  useMutation,
  useQuery,
  useQueryClient,
  type InferDataFromTag,
  type QueryKey,
  type UseMutationResult,
} from '@tanstack/react-query';
import { ApiError, call, client } from './client';
import type { paths } from './generated/schema';

type Query<P extends keyof paths> = paths[P] extends { get: { parameters: { query?: infer Q } } } ? NonNullable<Q> : never;

export type FieldsQuery = Query<'/api/v1/fields'>;
export type JobsQuery = Query<'/api/v1/jobs'>;
export type JobReportQuery = Query<'/api/v1/jobs/{job_id}/report'>;
export type AlertGroupsQuery = Query<'/api/v1/alerts/groups'>;
export type TrackQuery = Query<'/api/v1/machines/{machine_id}/track'>;
export type PlanCellsQuery = Query<'/api/v1/plans/{plan_id}/cells'>;
export type AsAppliedQuery = Query<'/api/v1/jobs/{job_id}/as-applied'>;

/** Query keys, one home. A prefix invalidates everything under it. */
export const qk = {
  farms: () => ['farms'] as const,
  fields: (q?: FieldsQuery) => (q ? (['fields', 'list', q] as const) : (['fields', 'list'] as const)),
  field: (id: number) => ['fields', id] as const,
  fieldPlans: (id: number) => ['fields', id, 'plans'] as const,
  soilSamples: (id: number) => ['fields', id, 'soil-samples'] as const,
  soilImports: (id: number) => ['fields', id, 'soil-imports'] as const,
  /** A field's imagery, or the organisation's (fieldId undefined). */
  imagery: (fieldId?: number) => (fieldId != null ? (['fields', fieldId, 'imagery'] as const) : (['imagery'] as const)),
  plan: (id: number) => ['plans', id] as const,
  planRoute: (id: number) => ['plans', id, 'route'] as const,
  planPrescriptions: (id: number) => ['plans', id, 'prescriptions'] as const,
  planCells: (id: number, q: PlanCellsQuery) => ['plans', id, 'cells', q] as const,
  planCellsAll: (id: number) => ['plans', id, 'cells', 'all'] as const,
  prescription: (id: number) => ['prescriptions', id] as const,
  prescriptionVersion: (id: number, version: number) => ['prescriptions', id, 'versions', version] as const,
  machines: () => ['machines', 'list'] as const,
  machineStatus: () => ['machines', 'status'] as const,
  machine: (id: number) => ['machines', id] as const,
  machineTrack: (id: number, q: TrackQuery) => ['machines', id, 'track', q] as const,
  jobs: (q?: JobsQuery) => (q ? (['jobs', 'list', q] as const) : (['jobs', 'list'] as const)),
  job: (id: number) => ['jobs', id] as const,
  jobReport: (id: number, q: JobReportQuery) => ['jobs', id, 'report', q] as const,
  asApplied: (id: number, q: AsAppliedQuery) => ['jobs', id, 'as-applied', q] as const,
  alertGroups: (q?: AlertGroupsQuery) => (q ? (['alerts', 'groups', q] as const) : (['alerts', 'groups'] as const)),
  exportFormats: () => ['export-formats'] as const,
};

/**
 * The app's cache: data counts as fresh for 10 s (screens switch back and forth without
 * refetching), client errors (4xx: missing, forbidden, invalid) are not retried because
 * retrying cannot change the answer, server/network errors once.
 */
export function makeQueryClient(): QueryClient {
  return new QueryClient({
    defaultOptions: {
      queries: {
        staleTime: 10_000,
        refetchOnWindowFocus: false,
        retry: (n, e) => !(e instanceof ApiError && e.status < 500) && n < 1,
      },
    },
  });
}

/** What a hook caller may set: polling (ms, or a function of the data) and whether to run. */
export interface HookOptions<T> {
  /** Poll every so many ms; a function may stop polling (return false) e.g. once a job is final. */
  refetchInterval?: number | false | ((data: T | undefined) => number | false);
  /** false = do not fetch yet (e.g. an id not known yet). */
  enabled?: boolean;
  /** How long an answer counts as fresh (ms; default 10 s): 0 = refetch whenever the screen opens. */
  staleTime?: number;
}

function poll<T>(o?: HookOptions<T>) {
  const r = o?.refetchInterval;
  return {
    enabled: o?.enabled,
    ...(o?.staleTime !== undefined ? { staleTime: o.staleTime } : {}),
    refetchInterval: typeof r === 'function' ? (q: { state: { data: T | undefined } }) => r(q.state.data) : r,
  };
}

/** `useAllPlanCells` reads pages this large, up to this many cells (larger grids use the tiles). */
const PLAN_CELLS_PAGE = 1000;
const PLAN_CELLS_MAX = 20_000;

const has = (id: number | null | undefined): id is number => id != null && Number.isFinite(id);

/** The option factories behind the hooks (also for `queryClient.fetchQuery` / prefetching). */
export const queries = {
  farms: () => queryOptions({ queryKey: qk.farms(), queryFn: () => call(client.GET('/api/v1/farms')) }),
  fields: (q: FieldsQuery = {}) =>
    queryOptions({ queryKey: qk.fields(q), queryFn: () => call(client.GET('/api/v1/fields', { params: { query: q } })) }),
  field: (id: number) =>
    queryOptions({
      queryKey: qk.field(id),
      queryFn: () => call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: id } } })),
    }),
  fieldPlans: (id: number) =>
    queryOptions({
      queryKey: qk.fieldPlans(id),
      queryFn: () => call(client.GET('/api/v1/fields/{field_id}/plans', { params: { path: { field_id: id } } })),
    }),
  soilSamples: (id: number) =>
    queryOptions({
      queryKey: qk.soilSamples(id),
      queryFn: () => call(client.GET('/api/v1/fields/{field_id}/soil-samples', { params: { path: { field_id: id } } })),
    }),
  soilImports: (id: number) =>
    queryOptions({
      queryKey: qk.soilImports(id),
      queryFn: () => call(client.GET('/api/v1/fields/{field_id}/soil-imports', { params: { path: { field_id: id } } })),
    }),
  imagery: (fieldId?: number) =>
    queryOptions({
      queryKey: qk.imagery(fieldId),
      queryFn: () =>
        call(
          fieldId != null
            ? client.GET('/api/v1/fields/{field_id}/imagery', { params: { path: { field_id: fieldId } } })
            : client.GET('/api/v1/imagery'),
        ),
    }),
  plan: (id: number) =>
    queryOptions({
      queryKey: qk.plan(id),
      queryFn: () => call(client.GET('/api/v1/plans/{plan_id}', { params: { path: { plan_id: id } } })),
    }),
  planRoute: (id: number) =>
    queryOptions({
      queryKey: qk.planRoute(id),
      queryFn: () => call(client.GET('/api/v1/plans/{plan_id}/route', { params: { path: { plan_id: id } } })),
    }),
  planPrescriptions: (id: number) =>
    queryOptions({
      queryKey: qk.planPrescriptions(id),
      queryFn: () => call(client.GET('/api/v1/plans/{plan_id}/prescriptions', { params: { path: { plan_id: id } } })),
    }),
  planCells: (id: number, q: PlanCellsQuery) =>
    queryOptions({
      queryKey: qk.planCells(id, q),
      queryFn: () => call(client.GET('/api/v1/plans/{plan_id}/cells', { params: { path: { plan_id: id }, query: q } })),
    }),
  planCellsAll: (id: number) =>
    queryOptions({
      queryKey: qk.planCellsAll(id),
      queryFn: async (): Promise<GeoJSON.FeatureCollection> => {
        const features: GeoJSON.Feature[] = [];
        for (let offset = 0; offset < PLAN_CELLS_MAX; offset += PLAN_CELLS_PAGE) {
          const r = await call(
            client.GET('/api/v1/plans/{plan_id}/cells', { params: { path: { plan_id: id }, query: { limit: PLAN_CELLS_PAGE, offset } } }),
          );
          features.push(...(r.features as unknown as GeoJSON.Feature[]));
          if (r.features.length < PLAN_CELLS_PAGE) break;
        }
        return { type: 'FeatureCollection', features };
      },
    }),
  prescription: (id: number) =>
    queryOptions({
      queryKey: qk.prescription(id),
      queryFn: () => call(client.GET('/api/v1/prescriptions/{rx_id}', { params: { path: { rx_id: id } } })),
    }),
  prescriptionVersion: (id: number, version: number) =>
    queryOptions({
      queryKey: qk.prescriptionVersion(id, version),
      queryFn: () =>
        call(client.GET('/api/v1/prescriptions/{rx_id}/versions/{version}', { params: { path: { rx_id: id, version } } })),
      staleTime: Infinity, // a stored version never changes
    }),
  machines: () => queryOptions({ queryKey: qk.machines(), queryFn: () => call(client.GET('/api/v1/machines')) }),
  /** Machines a job can be sent to: not those an import created to hold other terminals' logs. */
  sendableMachines: () =>
    queryOptions({
      queryKey: [...qk.machines(), 'sendable'] as const,
      queryFn: () => call(client.GET('/api/v1/machines', { params: { query: { sendable: true } } })),
    }),
  machineStatus: () => queryOptions({ queryKey: qk.machineStatus(), queryFn: () => call(client.GET('/api/v1/machines/status')) }),
  machine: (id: number) =>
    queryOptions({
      queryKey: qk.machine(id),
      queryFn: () => call(client.GET('/api/v1/machines/{machine_id}', { params: { path: { machine_id: id } } })),
    }),
  machineTrack: (id: number, q: TrackQuery) =>
    queryOptions({
      queryKey: qk.machineTrack(id, q),
      queryFn: () => call(client.GET('/api/v1/machines/{machine_id}/track', { params: { path: { machine_id: id }, query: q } })),
    }),
  jobs: (q: JobsQuery = {}) =>
    queryOptions({ queryKey: qk.jobs(q), queryFn: () => call(client.GET('/api/v1/jobs', { params: { query: q } })) }),
  job: (id: number) =>
    queryOptions({
      queryKey: qk.job(id),
      queryFn: () => call(client.GET('/api/v1/jobs/{job_id}', { params: { path: { job_id: id } } })),
    }),
  jobReport: (id: number, q: JobReportQuery = {}) =>
    queryOptions({
      queryKey: qk.jobReport(id, q),
      queryFn: () => call(client.GET('/api/v1/jobs/{job_id}/report', { params: { path: { job_id: id }, query: q } })),
      // Not kept once no screen shows it: a report is a moving aggregate (and may be large),
      // so a revisit reads it anew behind the loading state instead of opening on old totals.
      gcTime: 0,
    }),
  asApplied: (id: number, q: AsAppliedQuery) =>
    queryOptions({
      queryKey: qk.asApplied(id, q),
      queryFn: () => call(client.GET('/api/v1/jobs/{job_id}/as-applied', { params: { path: { job_id: id }, query: q } })),
    }),
  alertGroups: (q: AlertGroupsQuery = {}) =>
    queryOptions({
      queryKey: qk.alertGroups(q),
      queryFn: () => call(client.GET('/api/v1/alerts/groups', { params: { query: q } })),
    }),
  exportFormats: () =>
    queryOptions({
      queryKey: qk.exportFormats(),
      queryFn: () => call(client.GET('/api/v1/export-formats')),
      staleTime: Infinity, // the server's formats change only with a new server
    }),
};

/** The data type of a `queries.*` factory (read from its tagged query key). */
type Data<F extends (...a: never[]) => { queryKey: QueryKey }> = InferDataFromTag<unknown, ReturnType<F>['queryKey']>;

// --- one hook per resource -------------------------------------------------------------

/** The export formats the server writes (its registry): the export menus are built from it. */
export const useExportFormats = () => useQuery(queries.exportFormats());

export const useFarms = (o?: HookOptions<Data<typeof queries.farms>>) => useQuery({ ...queries.farms(), ...poll(o) });

/** GET /fields with a filter (`{ q, farm_id, limit }`); each filter is its own cache entry. */
export const useFields = (q: FieldsQuery = {}, o?: HookOptions<Data<typeof queries.fields>>) =>
  // a new filter keeps showing the previous list until its answer arrives (no empty flash)
  useQuery({ ...queries.fields(q), ...poll(o), placeholderData: keepPreviousData });

/** One field (undefined/NaN id = not fetched). */
export const useField = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.field>>) =>
  useQuery({ ...queries.field(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useFieldPlans = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.fieldPlans>>) =>
  useQuery({ ...queries.fieldPlans(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useSoilSamples = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.soilSamples>>) =>
  useQuery({ ...queries.soilSamples(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useSoilImports = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.soilImports>>) =>
  useQuery({ ...queries.soilImports(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

/** A field's imagery, or the organisation's when `fieldId` is undefined. */
export const useImagery = (fieldId?: number, o?: HookOptions<Data<typeof queries.imagery>>) =>
  useQuery({ ...queries.imagery(fieldId), ...poll(o) });

export const usePlan = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.plan>>) =>
  useQuery({ ...queries.plan(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const usePlanRoute = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.planRoute>>) =>
  useQuery({ ...queries.planRoute(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const usePlanPrescriptions = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.planPrescriptions>>) =>
  useQuery({ ...queries.planPrescriptions(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

/** One page of a plan's cells (GeoJSON). */
export const usePlanCells = (id: number | null | undefined, q: PlanCellsQuery, o?: HookOptions<Data<typeof queries.planCells>>) =>
  useQuery({ ...queries.planCells(id ?? -1, q), ...poll(o), enabled: has(id) && o?.enabled !== false });

/** Every cell of a plan as GeoJSON, in pages (at most 20 000): small grids drawn without tiles (sensor-job maps). */
export const useAllPlanCells = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.planCellsAll>>) =>
  useQuery({ ...queries.planCellsAll(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const usePrescription = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.prescription>>) =>
  useQuery({ ...queries.prescription(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

/** A stored version of a prescription (never changes, cached for good). */
export const usePrescriptionVersion = (
  id: number | null | undefined,
  version: number | null | undefined,
  o?: HookOptions<Data<typeof queries.prescriptionVersion>>,
) =>
  useQuery({
    ...queries.prescriptionVersion(id ?? -1, version ?? -1),
    ...poll(o),
    enabled: has(id) && has(version) && o?.enabled !== false,
  });

export const useMachines = (o?: HookOptions<Data<typeof queries.machines>>) => useQuery({ ...queries.machines(), ...poll(o) });
export const useSendableMachines = (o?: HookOptions<Data<typeof queries.sendableMachines>>) =>
  useQuery({ ...queries.sendableMachines(), ...poll(o) });

export const useMachineStatus = (o?: HookOptions<Data<typeof queries.machineStatus>>) =>
  useQuery({ ...queries.machineStatus(), ...poll(o) });

export const useMachine = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.machine>>) =>
  useQuery({ ...queries.machine(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useMachineTrack = (id: number | null | undefined, q: TrackQuery, o?: HookOptions<Data<typeof queries.machineTrack>>) =>
  useQuery({ ...queries.machineTrack(id ?? -1, q), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useJobs = (q: JobsQuery = {}, o?: HookOptions<Data<typeof queries.jobs>>) => useQuery({ ...queries.jobs(q), ...poll(o) });

export const useJob = (id: number | null | undefined, o?: HookOptions<Data<typeof queries.job>>) =>
  useQuery({ ...queries.job(id ?? -1), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useJobReport = (id: number | null | undefined, q: JobReportQuery = {}, o?: HookOptions<Data<typeof queries.jobReport>>) =>
  useQuery({ ...queries.jobReport(id ?? -1, q), ...poll(o), enabled: has(id) && o?.enabled !== false });

/** One page of a job's as-applied records. */
export const useAsApplied = (id: number | null | undefined, q: AsAppliedQuery, o?: HookOptions<Data<typeof queries.asApplied>>) =>
  useQuery({ ...queries.asApplied(id ?? -1, q), ...poll(o), enabled: has(id) && o?.enabled !== false });

export const useAlertGroups = (q: AlertGroupsQuery = {}, o?: HookOptions<Data<typeof queries.alertGroups>>) =>
  useQuery({ ...queries.alertGroups(q), ...poll(o) });

// --- edits -----------------------------------------------------------------------------

/**
 * An edit (POST/PATCH/DELETE) that refetches what it changed: on success every key
 * `invalidate(result, variables)` returns is invalidated (prefix match) and the mutation's
 * promise settles only after the active ones have refetched, so a screen that navigates or
 * shows "saved" afterwards shows fresh data. `error` / `isPending` drive the form's state.
 */
export function useApiMutation<TVars, TData>(
  fn: (vars: TVars) => Promise<TData>,
  opts: { invalidate?: (data: TData, vars: TVars) => readonly QueryKey[] } = {},
): UseMutationResult<TData, unknown, TVars> {
  const qc = useQueryClient();
  return useMutation<TData, unknown, TVars>({
    mutationFn: fn,
    onSuccess: (data, vars) => invalidateAll(qc, opts.invalidate?.(data, vars) ?? []),
  });
}

/** Invalidate several keys (prefix match) and wait for the active queries to refetch. */
export function invalidateAll(qc: QueryClient, keys: readonly QueryKey[]): Promise<void> {
  return Promise.all(keys.map((queryKey) => qc.invalidateQueries({ queryKey }))).then(() => undefined);
}

/** `const refresh = useInvalidate(); await refresh(qk.field(id));` */
export function useInvalidate(): (...keys: QueryKey[]) => Promise<void> {
  const qc = useQueryClient();
  return (...keys) => invalidateAll(qc, keys);
}
