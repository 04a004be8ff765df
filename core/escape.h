/* Text written into other formats: names (materials, patches, layouts), ids, record
 * values, titles and file paths, one function per format, so that what is written
 * reads back as it went in, or is refused with a message naming the field, the byte
 * and why (docs/formats.md, "Text in written files"). No writer prints such text
 * into a file any other way.
 *
 *   XML (Mitsuba scenes)   kg_xml_put writes; kg_xml_check refuses what XML 1.0
 *                          cannot hold at all.
 *   HTML (report.html)     kg_html_put writes; HTML holds any UTF-8 text.
 *   JSON                   jansson writes every JSON file and escapes for it; text
 *                          enters it through kg_json_text (UTF-8 checked) or, for
 *                          kogei's own messages, kg_json_message (never dropped).
 *   CGATS                  kg_cgats_put writes a cell or a keyword's value;
 *                          kg_cgats_check refuses what CGATS cannot quote.
 *   ENVI header            kg_envi_check: the format has no escapes, so a value
 *                          that would read back otherwise is refused; free text
 *                          (an object's record in a description) goes through
 *                          kg_envi_put_quoted, a JSON string without braces.
 *   CSV (tables of names)  kg_csv_put (RFC 4180 quoting).
 *   TIFF                   Software, "kogei VERSION"; the master's identity
 *                          (ImageDescription, Artist, Copyright: a record's values,
 *                          which hold no control character) and its XMP packet,
 *                          written with kg_xml_put.
 *
 * The checks take `what`, the file and field for the message ("out.xml: material
 * 'gold': name"); messages show an offending character as U+XXXX or a byte as 0xXX,
 * never raw. */
#ifndef KG_ESCAPE_H
#define KG_ESCAPE_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "error.h"

/* The well-formed UTF-8 character at s (at most n bytes): its length, 1 to 4, with
 * its code point in *cp; 0 when the bytes there are not one (an invalid or truncated
 * sequence, an overlong form, a surrogate, a code point above U+10FFFF). */
int kg_utf8_char(const char *s, size_t n, uint32_t *cp);

/* 0 when s is well-formed UTF-8; else KG_EINVAL, "<what>: byte N (0xXX) is not
 * UTF-8: <format> text is UTF-8". */
int kg_utf8_check(const char *what, const char *s, const char *format, kg_err *err);

/* 0 when s is UTF-8 without control characters (U+0000-U+001F, U+007F-U+009F: tabs
 * and line breaks included); else KG_EINVAL, "<what>: U+XXXX at byte N: expected no
 * control characters", or the byte that is not UTF-8. For names that must read the
 * same in every format and on a terminal. */
int kg_text_check_controls(const char *what, const char *s, kg_err *err);

/* XML 1.0 character data, attribute values (in double or single quotes) and comment
 * text alike: & < > " ' as entities; tab, line feed and carriage return as character
 * references (an attribute value keeps them so); a '-' that follows a '-' or ends the
 * text as &#45;, so no "--" and no trailing '-' can close a comment (a comment shows
 * the references as written: nothing in a comment is data). A character XML 1.0
 * cannot hold (what kg_xml_check refuses) is written as U+FFFD. */
void kg_xml_put(FILE *fp, const char *s);
/* 0 when XML 1.0 can hold s: well-formed UTF-8 without the C0 controls other than tab,
 * line feed and carriage return and without U+FFFE and U+FFFF (XML has no way to
 * write those, not even as references). Else KG_EINVAL naming the character. */
int kg_xml_check(const char *what, const char *s, kg_err *err);

/* HTML text and quoted attribute values: & < > " ' as entities, a carriage return as
 * &#13; (a parser would turn a raw one into a line feed). Every other character is
 * written as it is; a byte that is not UTF-8 (not in the report's text, which comes
 * from JSON) as U+FFFD. */
void kg_html_put(FILE *fp, const char *s);
/* printf, then the result as kg_html_put writes it (no length limit). */
void kg_html_putf(FILE *fp, const char *fmt, ...) KG_PRINTF(2, 3);

/* A JSON string of s (jansson escapes it when written), or NULL with KG_EINVAL,
 * "<what>: byte N ... is not UTF-8: JSON text is UTF-8", or KG_ENOMEM. */
json_t *kg_json_text(const char *what, const char *s, kg_err *err);
/* A JSON string of one of kogei's messages, which may quote a file's bytes or have
 * been cut to a buffer's length: a byte that is not UTF-8 is written as U+FFFD, so
 * the message is never dropped. NULL only when out of memory. */
json_t *kg_json_message(const char *s);

/* A word CGATS reserves for its structure (BEGIN_DATA, KEYWORD, ...). */
int kg_cgats_reserved(const char *s);
/* 0 when s can be written as CGATS text: no double quote and no line break (CGATS
 * quotes text between double quotes and has no escape inside them). Else KG_EINVAL
 * naming the character. */
int kg_cgats_check(const char *what, const char *s, kg_err *err);
/* A CGATS value that kg_cgats_check accepted: between double quotes when `quoted`
 * (keyword values) or when it is not one plain word (empty, blanks, '#', a reserved
 * word), else as it is. Read back by kg_cgats_parse as the same text. */
void kg_cgats_put(FILE *fp, const char *s, int quoted);

/* A CSV field (RFC 4180): between double quotes, each inner one doubled, when it holds
 * a comma, a double quote, a line break or white space at either end; else as it is. */
void kg_csv_put(FILE *fp, const char *s);

/* 0 when s can stand in an ENVI header value in braces and read back the same: as an
 * element of a list (`list`: band names, class names) no comma and no line break, and
 * not empty; as a whole value (description) line feeds allowed. Neither may hold a
 * brace or a carriage return, or begin or end with white space (readers trim it).
 * Else KG_EINVAL naming the character. */
int kg_envi_check(const char *what, const char *s, int list, kg_err *err);
/* s as a JSON string literal that an ENVI description in braces can hold: between
 * double quotes, '"' and '\\' escaped with a backslash, '{' and '}' as \u007b and
 * \u007d, control characters as \uXXXX (\n, \r, \t as such), every other character
 * (UTF-8) as it is; a byte that is not UTF-8 as U+FFFD. Holds no brace, carriage return
 * or line feed, so kg_envi_check accepts it, and any JSON parser reads s back. */
void kg_envi_put_quoted(FILE *fp, const char *s);

#endif
