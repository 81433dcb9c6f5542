"""Request and response models of the REST API, one module per resource.

Conventions (every route follows them; ``tests/system/test_contract.py`` checks the
OpenAPI document for them):

- Request bodies subclass ``base.In`` (unknown fields are refused with a 422 naming
  the field); response bodies subclass ``base.Out`` (the document says exactly which
  fields come back, so the generated TypeScript client is exact). Stored JSON blobs
  whose keys grow over time (a version's summary, a report) are ``base.Open`` models:
  their known keys are typed, others pass through.
- One name per field: a figure appears once, under its unit-suffixed name.
- Every router is created with ``responses=errors.ERRORS`` (401/403/404/409/422/503 in
  the one error shape ``errors.ErrorOut``); file downloads and tiles declare their
  media types with ``files.file_response``.
"""
