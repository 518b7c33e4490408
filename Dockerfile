# robomach workbench: viser 3D scene (8080), REST API + pendant page (8000).
#
#   docker build -t robomach .
#   docker run -p 8000:8000 -p 8080:8080 -e ROBOMACH_TOKEN=$(openssl rand -hex 16) \
#       -v robomach-data:/data robomach
#
# The container binds 0.0.0.0, so the server refuses to start without ROBOMACH_TOKEN (at least
# 16 characters); mutating REST calls must then send "Authorization: Bearer <token>".
# The viser port has no authentication of its own: publish 8080 only where you trust the network.

FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MPLBACKEND=Agg \
    NUMBA_CACHE_DIR=/tmp/numba-cache

RUN useradd --create-home --uid 1000 robomach \
    && mkdir -p /data \
    && chown robomach:robomach /data

WORKDIR /app

# Dependencies first (a layer that survives source edits): an editable install of the project's
# metadata with empty packages; the sources copied below are what the editable install points at.
COPY pyproject.toml README.md ./
RUN mkdir -p app robomach_core \
    && touch app/__init__.py robomach_core/__init__.py \
    && pip install -e .

COPY robomach_core ./robomach_core
COPY app ./app
COPY static ./static

USER robomach

ENV ROBOMACH_HOST=0.0.0.0 \
    ROBOMACH_PORT=8000 \
    ROBOMACH_VISER_PORT=8080 \
    ROBOMACH_DATA=/data

VOLUME ["/data"]
EXPOSE 8000 8080

HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/api/health', timeout=4)"

# SIGTERM (docker stop) and SIGINT both shut down gracefully: jobs cancelled, viser stopped,
# the database closed. A kill at any other moment cannot corrupt it (SQLite WAL, FULL sync).
ENTRYPOINT ["robomach", "serve"]
