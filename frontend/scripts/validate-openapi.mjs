// Validates an OpenAPI document against the OpenAPI 3.1 specification (Redocly's "spec"
// rule: structure, types, $refs) plus the checks FieldRx relies on. Prints each problem
// with its JSON pointer; exits 1 when there is one. Usage: node scripts/validate-openapi.mjs FILE
import { readFileSync } from 'node:fs';
import { createConfig, lintFromString } from '@redocly/openapi-core';

const file = process.argv[2] ?? 'src/api/openapi.json';
const config = await createConfig({
  rules: {
    struct: 'error', // the OpenAPI 3.1 structure (what openapi-spec-validator checks)
    'no-unresolved-refs': 'error',
    'operation-operationId-unique': 'error',
    'path-parameters-defined': 'error',
    'no-identical-paths': 'error',
    'operation-2xx-response': 'error',
    'security-defined': 'error',
  },
});
const problems = await lintFromString({ source: readFileSync(file, 'utf8'), absoluteRef: file, config });
const errors = problems.filter((p) => p.severity === 'error');
for (const p of errors) console.log(`${p.ruleId}: ${p.message} at ${p.location?.[0]?.pointer ?? '?'}`);
console.log(`${errors.length} problem(s) in ${file}`);
process.exit(errors.length ? 1 : 0);
