# FieldRx API / worker image.
FROM node:20-bookworm-slim AS frontend
WORKDIR /src/frontend
COPY frontend/package.json frontend/package-lock.json ./
RUN npm ci --no-audit --no-fund
COPY frontend/ ./
RUN npm run build

FROM python:3.11-slim-bookworm
WORKDIR /app
COPY requirements.lock ./
COPY edge_agent/ edge_agent/
COPY backend/ backend/
RUN pip install --no-cache-dir -c requirements.lock ./edge_agent ./backend
COPY alembic.ini ./
COPY migrations/ migrations/
COPY --from=frontend /src/frontend/dist /app/frontend/dist
ENV FIELDRX_FRONTEND_DIST=/app/frontend/dist
EXPOSE 8000
# ingest workers' slot locks (docker-compose.yml mounts a shared volume here)
RUN mkdir -p /var/lib/fieldrx-worker && chown nobody /var/lib/fieldrx-worker
USER nobody
CMD ["fieldrx", "serve", "--host", "0.0.0.0", "--port", "8000"]
