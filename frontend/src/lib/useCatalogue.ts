import { useQuery, useQueryClient } from '@tanstack/react-query';
import { call, client } from '../api/client';
import type { Crop, Product } from './rxform';

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
