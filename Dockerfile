# syntax=docker/dockerfile:1
# accelcal: multi-stage build; the runtime image holds the binary only and
# runs as an unprivileged user with its database on a volume.

FROM rust:1.95-slim-bookworm AS builder
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY core ./core
COPY testkit ./testkit
COPY src ./src
COPY benches ./benches
COPY openapi.yaml ./
COPY examples ./examples
RUN cargo build --release --locked --bin accelcal \
    && mkdir -p /data

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=builder /src/target/release/accelcal /usr/local/bin/accelcal
COPY --from=builder --chown=65532:65532 /data /data
ENV ACCELCAL_LISTEN=0.0.0.0:8080 \
    ACCELCAL_DATABASE_URL=/data/accelcal.db \
    ACCELCAL_LOG_FORMAT=json
VOLUME ["/data"]
EXPOSE 8080
USER 65532:65532
HEALTHCHECK --interval=30s --timeout=5s --start-period=5s --retries=3 \
    CMD ["/usr/local/bin/accelcal", "health", "--url", "http://127.0.0.1:8080"]
ENTRYPOINT ["/usr/local/bin/accelcal"]
CMD ["serve"]
