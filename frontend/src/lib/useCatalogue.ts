import { useQuery, useQueryClient } from '@tanstack/react-query';
import { call, client } from '../api/client';
import type { Crop, FormDefaults, Product } from './rxform';

/** Query key of the product catalogue (GET /products), beside `api/hooks.ts`'s `qk`. */
export const CATALOGUE_KEY = ['products'] as const;

/** The organisation's product catalogue and the crop defaults (GET /products); reload after an add. */
export function useCatalogue(): { crops: Crop[]; products: Product[]; reload: () => Promise<void>; error: unknown } {
  const q = useQuery({ queryKey: CATALOGUE_KEY, queryFn: () => call(client.GET('/api/v1/products')) });
  const qc = useQueryClient();
  return {
    crops: q.data?.crops ?? [],
    products: q.data?.products ?? [],
    reload: () => qc.invalidateQueries({ queryKey: CATALOGUE_KEY }),
    error: q.error,
  };
}

/**
 * What the prescription forms start from on a plan's field (GET /fields/{id}/rx-defaults:
 * the field's crop, its last prescription's product and yield goal). ``ready`` once known
 * (or failed: the forms then start from the catalogue's first crop, as before).
 */
export function usePlanFormDefaults(planId: number): { data: FormDefaults | null; ready: boolean } {
  const q = useQuery({
    queryKey: ['rx-defaults', planId],
    queryFn: async () => {
      const plan = await call(client.GET('/api/v1/plans/{plan_id}', { params: { path: { plan_id: planId } } }));
      return call(client.GET('/api/v1/fields/{field_id}/rx-defaults', { params: { path: { field_id: plan.field_id } } }));
    },
  });
  return { data: q.data ?? null, ready: !q.isPending };
}
