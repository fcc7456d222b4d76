"""The server's own refusals and answers a user can cause, in Spanish, English and Portuguese (one table).

The ingestion's messages name a file (:mod:`app.pipeline.ingestion.messages`); these are about a request or a
session as a whole: ``request.*`` the web API's refusals of a request (:mod:`app.web.limits`,
:mod:`app.web.api.recordings`), ``session.*`` what the upload checks answer (:mod:`app.store.checks`).
Same templates and rules as the ingestion's catalogue (``{name}`` placeholders, a sentence that ends saying
what to do); :func:`render` and :func:`message_dict` are that module's, on this table.
"""

from __future__ import annotations

from typing import Any, Mapping

from app.pipeline.ingestion.messages import message_dict as _message_dict
from app.pipeline.ingestion.messages import render as _render

CATALOGUE: dict[str, dict[str, str]] = {
    "session.check_too_slow": {
        "en": "The files could not be checked within {seconds} s and the check was stopped; check that each "
              "file is a recording of this session (a file made to be slow to read is refused), delete the "
              "wrong one and upload it again.",
        "es": "Los archivos no se pudieron comprobar en {seconds} s y la comprobación se detuvo; compruebe que "
              "cada archivo es una grabación de esta sesión (se rechaza un archivo hecho para ser lento de leer), "
              "borre el equivocado y súbalo de nuevo.",
        "pt": "Os arquivos não puderam ser verificados em {seconds} s e a verificação foi interrompida; verifique "
              "se cada arquivo é uma gravação desta sessão (um arquivo feito para ser lento de ler é recusado), "
              "apague o errado e envie-o de novo."},
    "session.check_stopped": {
        "en": "The files could not be checked: the check stopped unexpectedly; delete the file you added last and "
              "upload it again, and if it happens again tell your ChakaMo administrator.",
        "es": "Los archivos no se pudieron comprobar: la comprobación se detuvo inesperadamente; borre el último "
              "archivo que añadió y súbalo de nuevo, y si vuelve a ocurrir avise a su administrador de ChakaMo.",
        "pt": "Os arquivos não puderam ser verificados: a verificação parou inesperadamente; apague o último "
              "arquivo que adicionou e envie-o de novo, e se voltar a acontecer avise o seu administrador do "
              "ChakaMo."},
    "request.host_not_allowed": {
        "en": "This server does not answer to the address {host}; use the address your ChakaMo administrator "
              "gave you (CHAKAMO_ALLOWED_HOSTS).",
        "es": "Este servidor no responde a la dirección {host}; use la dirección que le dio su administrador de "
              "ChakaMo (CHAKAMO_ALLOWED_HOSTS).",
        "pt": "Este servidor não responde ao endereço {host}; use o endereço que o seu administrador do ChakaMo "
              "lhe deu (CHAKAMO_ALLOWED_HOSTS)."},
    "request.public_url_missing": {
        "en": "The FHIR export needs this server's public address, which is not set; ask your ChakaMo "
              "administrator to set CHAKAMO_PUBLIC_URL (or CHAKAMO_ALLOWED_HOSTS).",
        "es": "La exportación FHIR necesita la dirección pública de este servidor, que no está configurada; pida "
              "a su administrador de ChakaMo que configure CHAKAMO_PUBLIC_URL (o CHAKAMO_ALLOWED_HOSTS).",
        "pt": "A exportação FHIR precisa do endereço público deste servidor, que não está configurado; peça ao "
              "seu administrador do ChakaMo que configure CHAKAMO_PUBLIC_URL (ou CHAKAMO_ALLOWED_HOSTS)."},
    "request.body_too_large": {
        "en": "The request body is larger than {limit_kb} kB; requests other than uploads of recordings take "
              "small JSON bodies — send less.",
        "es": "El cuerpo de la petición ocupa más de {limit_kb} kB; las peticiones que no son subidas de "
              "grabaciones llevan cuerpos JSON pequeños: envíe menos.",
        "pt": "O corpo da requisição ocupa mais de {limit_kb} kB; as requisições que não são envios de gravações "
              "levam corpos JSON pequenos: envie menos."},
    "request.multipart_malformed": {
        "en": "The multipart body is malformed; send the files with a standard form upload.",
        "es": "El cuerpo multipart está mal formado; envíe los archivos con un formulario estándar.",
        "pt": "O corpo multipart está malformado; envie os arquivos com um formulário padrão."},
    "request.boundary_too_long": {
        "en": "The multipart boundary has {length} characters; a boundary has 1 to 70 (RFC 2046) — send the "
              "files with a standard form upload.",
        "es": "El delimitador multipart tiene {length} caracteres; un delimitador tiene de 1 a 70 (RFC 2046): "
              "envíe los archivos con un formulario estándar.",
        "pt": "O delimitador multipart tem {length} caracteres; um delimitador tem de 1 a 70 (RFC 2046): envie "
              "os arquivos com um formulário padrão."},
    "request.file_name_controls": {
        "en": "File name {name} holds invisible characters that reorder how it is shown (Unicode bidirectional "
              "controls); rename the file (letters, digits, - _ .).",
        "es": "El nombre de archivo {name} contiene caracteres invisibles que cambian el orden en que se muestra "
              "(controles bidireccionales de Unicode); cambie el nombre del archivo (letras, dígitos, - _ .).",
        "pt": "O nome de arquivo {name} contém caracteres invisíveis que mudam a ordem em que é mostrado "
              "(controles bidirecionais do Unicode); renomeie o arquivo (letras, dígitos, - _ .)."},
    "request.disk_full": {
        "en": "The server's disk is full, so the files could not be stored and none was recorded. Ask your "
              "ChakaMo administrator to free space, then upload them again.",
        "es": "El disco del servidor está lleno, así que los archivos no se pudieron guardar y no se registró "
              "ninguno. Pida a su administrador de ChakaMo que libere espacio y súbalos de nuevo.",
        "pt": "O disco do servidor está cheio, por isso os arquivos não puderam ser guardados e nenhum foi "
              "registrado. Peça ao seu administrador do ChakaMo que libere espaço e envie-os de novo."},
}


def render(code: str, params: Mapping[str, Any], lang: str = "en") -> str:
    """Message ``code`` of :data:`CATALOGUE` in ``lang`` (es/en/pt), filled from ``params``."""
    return _render(code, params, lang, CATALOGUE)


def message_dict(code: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """``{"code", "params", "message": {lang: text}}`` of :data:`CATALOGUE` for JSON answers."""
    return _message_dict(code, params, CATALOGUE)


__all__ = ["CATALOGUE", "message_dict", "render"]
