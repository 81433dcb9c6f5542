.PHONY: run test check setup lint
run:  ## set up everything and run the platform with demo data on http://127.0.0.1:8000
	scripts/run.sh
test: ## set up everything the tests need and run every test
	scripts/test.sh
check: ## the edit loop's quick checks: lint, types, dead code, unit tests of pure modules
	scripts/check.sh
setup:
	scripts/setup.sh
lint:
	.venv/bin/ruff check backend edge_agent tests bench
